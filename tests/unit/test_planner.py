"""Costmaps and the global planner, on small hand-made grids and on the simulator's worlds."""
import math

import numpy as np
import pytest

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap, RollingCostmap, footprint_radii
from turtlebot3c_navigation.global_planner import GlobalPlanner, PlanningError, path_length
from turtlebot3c_navigation.grid_info import GridInfo
from turtlebot3c_navigation.likelihood_field import distance_transform
from turtlebot3c_navigation.navigation_stack import costmap_params_for_model, make_costmaps
from turtlebot3c_sim.navigation_loop import world_layers
from turtlebot3c_sim.world import load_world

INFO = GridInfo(0.05, 60, 40, 0.0, 0.0)  # 3 m x 2 m


def wall_grid():
    """A wall across x = 1.5 m with a gap between y = 1.2 and 1.8 m."""
    occupied = np.zeros((INFO.height, INFO.width), bool)
    occupied[:24, 30] = True
    occupied[36:, 30] = True
    return occupied


def test_distance_transform_is_euclidean_distance_to_nearest_obstacle():
    rng = np.random.RandomState(3)
    occupied = rng.uniform(size=(30, 40)) < 0.02
    distances = distance_transform(occupied, 0.1, max_distance=10.0)
    rows, cols = np.nonzero(occupied)
    for row, col in [(0, 0), (15, 20), (29, 39), (7, 33)]:
        expected = np.hypot(rows - row, cols - col).min() * 0.1
        assert distances[row, col] == pytest.approx(expected)


def test_distance_transform_caps_far_cells_at_max_distance():
    occupied = np.zeros((50, 50), bool)
    occupied[0, 0] = True
    distances = distance_transform(occupied, 0.1, max_distance=1.0)
    assert distances[49, 49] == pytest.approx(1.0)
    assert distances[0, 5] == pytest.approx(0.5)


def test_footprint_radii_of_burger():
    inscribed, circumscribed = footprint_radii(get_model("burger").footprint)
    assert inscribed == pytest.approx(0.041)
    assert circumscribed == pytest.approx(math.hypot(0.105, 0.105))


def test_inflation_is_lethal_on_obstacles_inscribed_near_them_and_decays_away():
    costmap = Costmap(INFO, wall_grid(), robot_radius=0.15, inflation_radius=0.6, cost_scaling_factor=3.0)
    costs = costmap.costs
    assert costs[10, 30] == LETHAL
    assert costs[10, 28] == INSCRIBED  # 0.10 m from the wall
    assert 0 < costs[10, 24] < costs[10, 26] < INSCRIBED  # 0.30 m then 0.20 m away
    assert costs[10, 5] == 0  # 1.25 m away


def test_unknown_cells_have_no_information_cost():
    unknown = np.zeros((INFO.height, INFO.width), bool)
    unknown[:, 50:] = True
    costmap = Costmap(INFO, wall_grid(), unknown, robot_radius=0.15)
    assert costmap.costs[5, 55] == NO_INFORMATION


def test_plan_goes_through_the_gap_and_keeps_clear_of_the_wall():
    costmap = Costmap(INFO, wall_grid(), robot_radius=0.15, inflation_radius=0.6)
    plan = GlobalPlanner().plan(costmap, (0.5, 0.5), (2.5, 0.5))
    assert np.allclose(plan[0], (0.5, 0.5)) and np.allclose(plan[-1], (2.5, 0.5))
    crossing = plan[np.argmin(np.abs(plan[:, 0] - 1.525))]
    assert 1.3 < crossing[1] < 1.7
    assert (costmap.cost_at(plan[:, 0], plan[:, 1]) < INSCRIBED).all()
    assert np.hypot(*np.diff(plan, axis=0).T).max() <= 0.05 + 1e-9


def test_plan_is_no_longer_than_needed_around_a_wall():
    costmap = Costmap(INFO, wall_grid(), robot_radius=0.15, inflation_radius=0.6)
    plan = GlobalPlanner().plan(costmap, (0.5, 0.5), (2.5, 0.5))
    through_gap_centre = 2 * math.hypot(1.0, 1.0)
    assert 2.0 < path_length(plan) < 1.1 * through_gap_centre


def test_goal_inside_an_obstacle_is_unreachable_with_a_clear_reason():
    costmap = Costmap(INFO, wall_grid(), robot_radius=0.15)
    with pytest.raises(PlanningError, match="goal .* in or too close to an obstacle"):
        GlobalPlanner().plan(costmap, (0.5, 0.5), (1.52, 0.5))


def test_goal_behind_a_closed_wall_is_unreachable_with_a_clear_reason():
    occupied = wall_grid()
    occupied[:, 30] = True
    costmap = Costmap(INFO, occupied, robot_radius=0.15)
    with pytest.raises(PlanningError, match="no path from .* cut off"):
        GlobalPlanner().plan(costmap, (0.5, 0.5), (2.5, 0.5))


def test_goal_outside_the_map_is_refused():
    costmap = Costmap(INFO, wall_grid(), robot_radius=0.15)
    with pytest.raises(PlanningError, match="outside the map"):
        GlobalPlanner().plan(costmap, (0.5, 0.5), (9.0, 0.5))


def beams_towards(target_range, count=90):
    angles = np.linspace(-0.3, 0.3, count)
    return np.full(count, target_range), angles


def test_laser_marks_a_new_obstacle_and_clears_it_once_it_is_gone():
    costmap = Costmap(INFO, robot_radius=0.1)
    ranges, angles = beams_towards(1.0)
    costmap.update_from_scan((0.5, 1.0, 0.0), ranges, angles)
    assert costmap.cost_at(np.array([1.48]), np.array([1.0]))[0] == LETHAL
    costmap.update_from_scan((0.5, 1.0, 0.0), np.full(angles.size, np.inf), angles)
    assert costmap.cost_at(np.array([1.48]), np.array([1.0]))[0] == 0


def test_laser_returns_beyond_obstacle_range_clear_but_do_not_mark():
    costmap = Costmap(INFO, robot_radius=0.1, obstacle_range=1.0, raytrace_range=3.5)
    ranges, angles = beams_towards(1.8)
    costmap.update_from_scan((0.2, 1.0, 0.0), ranges, angles)
    assert not costmap.obstacles.any()


@pytest.mark.parametrize("reading, range_min, range_max, marks", [
    (2.5, 0.12, 2.5, False),  # a LIDAR that reports its range_max for no return
    (2.4, 0.12, 2.5, True),
    (0.0, 0.0, 8.0, False),  # one that reports 0 and declares no range_min
    (math.nan, 0.12, 8.0, False),
    (2.0, math.nan, math.nan, True),  # a damaged scan: limits that are not numbers stand for none
])
def test_a_no_return_reading_marks_no_obstacle_and_a_return_still_does(reading, range_min, range_max, marks):
    """No-return readings (each LIDAR marks them its own way) painted obstacles: a ring at range_max
    around the robot, or one at the sensor that left the robot no way to move."""
    costmap = Costmap(INFO, robot_radius=0.1, obstacle_range=3.0, raytrace_range=3.5)
    ranges, angles = beams_towards(reading)
    costmap.update_from_scan((0.2, 1.0, 0.0), ranges, angles, range_min, range_max=range_max)
    if marks:
        assert costmap.cost_at(np.array([0.2 + reading - 0.02]), np.array([1.0]))[0] == LETHAL
    else:
        assert not costmap.obstacles.any()


def test_a_beam_whose_angle_is_not_a_number_is_left_out():
    # It raised "cannot convert float NaN to integer" in move_base's scan callback, at every scan.
    costmap = Costmap(INFO, robot_radius=0.1)
    ranges, angles = beams_towards(1.0)
    angles[::2] = np.nan
    costmap.update_from_scan((0.5, 1.0, 0.0), ranges, angles)
    assert costmap.obstacles.sum() > 0
    costmap.update_from_scan((0.5, 1.0, 0.0), ranges, np.full(angles.size, np.nan))


def test_rolling_costmap_keeps_marks_in_place_when_the_window_moves():
    costmap = RollingCostmap(size=2.0, resolution=0.05, robot_radius=0.1)
    costmap.recenter(0.0, 0.0)
    ranges, angles = beams_towards(0.6)
    costmap.update_from_scan((0.0, 0.0, 0.0), ranges, angles)
    assert costmap.cost_at(np.array([0.59]), np.array([0.0]))[0] == LETHAL
    costmap.recenter(0.4, 0.3)
    assert costmap.cost_at(np.array([0.59]), np.array([0.0]))[0] == LETHAL
    costmap.recenter(5.0, 5.0)
    assert not costmap.obstacles.any()


@pytest.mark.parametrize("model", ["burger", "waffle_pi"])
def test_plans_in_turtlebot3_world_pass_between_the_pillars(model):
    world = load_world("turtlebot3_world")
    global_costmap, _ = make_costmaps(world_layers(world), costmap_params_for_model(get_model(model)))
    plan = GlobalPlanner().plan(global_costmap, (-2.0, -0.5), (2.0, 0.55))
    assert path_length(plan) < 5.0
    radius = footprint_radii(get_model(model).footprint)[1]
    assert not any(world.collides(x, y, radius) for x, y in plan)
