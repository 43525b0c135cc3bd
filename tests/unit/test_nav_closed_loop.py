"""Navigation closed-loop in the simulator's stepping API: localisation, planning and
control as the nodes run them, in simulated time."""
import math

import pytest
import yaml

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.dwa import dwa_params_for_model
from turtlebot3c_navigation.navigation_stack import pose_error
from turtlebot3c_sim.navigation_loop import closed_loop
from turtlebot3c_sim.world import find_world_file, world_from_description


def world_with(name, *obstacles):
    description = yaml.safe_load(find_world_file(name).read_text())
    description["obstacles"] = list(description["obstacles"]) + list(obstacles)
    return world_from_description(description, name)


def assert_at(pose, goal, xy_tolerance=0.05, yaw_tolerance=0.17):
    position_error, heading_error = pose_error(pose, goal)
    assert position_error <= xy_tolerance and heading_error <= yaw_tolerance, (pose, goal)


@pytest.mark.parametrize("model_name", ["burger", "waffle_pi"])
def test_goals_are_reached_within_tolerance_without_collision(model_name):
    loop = closed_loop(model_name=model_name, seed=1)
    for goal in [(0.55, -0.55, 1.57), (1.6, 0.55, 3.14), (-1.6, 1.65, 0.0)]:
        result = loop.run_to_goal(goal, timeout=120)
        assert result.state == "succeeded", result
        assert result.status_text == "goal reached"
        assert not result.collided
        assert_at(loop.sim.pose, goal)


def test_goal_inside_a_pillar_is_aborted_as_unreachable():
    loop = closed_loop()
    result = loop.run_to_goal((0.0, 0.0, 0.0), timeout=30)
    assert result.state == "aborted"
    assert "goal unreachable: goal (0.00, 0.00) is in or too close to an obstacle" in result.status_text
    assert result.duration < 1.0  # the static map alone rules it out: no waiting, no recovery
    assert result.distance_travelled < 0.01


def test_goal_outside_the_walls_is_aborted_as_cut_off():
    loop = closed_loop()
    result = loop.run_to_goal((-3.5, 0.0, 0.0), timeout=30)
    assert result.state == "aborted"
    assert result.status_text.startswith("goal unreachable: no path from (-2.0")
    assert "to (-3.50, 0.00): the goal is cut off by obstacles" in result.status_text


def test_obstacle_appearing_on_the_path_is_avoided_without_collision():
    loop = closed_loop(seed=3)
    goal = (0.55, -0.55, 0.0)
    blocked_world = world_with("turtlebot3_world", {"type": "box", "center": [-1.1, -0.55], "size": [0.3, 0.3]})

    def box_appears(running):
        if running.sim.time >= 2.0 and running.sim.world is not blocked_world:
            # The robot is on its way to the gap between the first two pillars: close it.
            assert running.sim.pose[0] < -1.5
            running.sim.world = blocked_world
    loop.obstacle_hook = box_appears
    result = loop.run_to_goal(goal, timeout=120)
    assert result.state == "succeeded", result
    assert not result.collided
    assert_at(loop.sim.pose, goal)
    costmap = loop.navigator.global_costmap
    rows, cols = costmap.info.world_to_cell([-1.3, -0.9], [-0.75, -0.35])
    assert costmap.obstacles[rows[0]:rows[1], cols[0]:cols[1]].any()  # the laser put the box on the costmap
    assert result.distance_travelled > 3.0  # around the pillars, not through the closed gap (2.6 m)


def test_wrong_initial_pose_is_corrected_by_global_localization_then_the_goal_is_reached():
    # In the living room, whose sofa and table no other room has (a view shared by several
    # places cannot tell them apart however long the robot looks).
    loop = closed_loop("house", seed=5, start=(2.5, 2.0, 0.0))
    x, y, yaw = loop.sim.pose
    loop.localizer.set_pose((x + 1.5, y + 1.0, yaw + 2.0), loop.odom_pose())
    assert pose_error(loop.estimated_pose(), loop.sim.pose)[0] > 1.5
    loop.localizer.global_localization()
    loop.advance(8.0, command=(0.0, 0.8))  # look around
    assert pose_error(loop.estimated_pose(), loop.sim.pose)[0] < 0.1
    goal = (2.5, -2.0, math.pi / 2)
    result = loop.run_to_goal(goal, timeout=120)
    assert result.state == "succeeded", result
    assert not result.collided
    assert_at(loop.sim.pose, goal)


def drive_recording(loop, goal):
    """run_to_goal, also returning the robot's (linear speed, heading) at every step."""
    samples = []
    loop.obstacle_hook = lambda running: samples.append((running.sim.velocity[0], running.sim.pose[2]))
    return loop.run_to_goal(goal, timeout=60), samples


def test_a_goal_behind_facing_the_robots_way_is_reached_backwards_without_turning_round():
    start, goal = (-2.0, -0.5, math.pi), (-1.2, -0.5, math.pi)  # 0.8 m behind the robot
    loop = closed_loop(model_name="waffle_pi", seed=2, start=start)
    result, samples = drive_recording(loop, goal)
    assert result.state == "succeeded", result
    assert not result.collided
    assert_at(loop.sim.pose, goal)
    speeds, headings = zip(*samples)
    assert min(speeds) < -0.2 and max(speeds) < 0.02
    assert max(pose_error((0.0, 0.0, heading), start)[1] for heading in headings) < 0.3


def test_with_move_forward_only_the_same_goal_is_reached_forwards_turning_round_twice():
    model = get_model("waffle_pi")
    start, goal = (-2.0, -0.5, math.pi), (-1.2, -0.5, math.pi)
    loop = closed_loop(model_name="waffle_pi", seed=2, start=start,
                       dwa_params=dwa_params_for_model(model, min_vel_x=0.0))
    result, samples = drive_recording(loop, goal)
    assert result.state == "succeeded", result
    assert not result.collided
    assert_at(loop.sim.pose, goal)
    speeds, headings = zip(*samples)
    assert min(speeds) > -0.02 and max(speeds) > 0.2
    assert max(pose_error((0.0, 0.0, heading), start)[1] for heading in headings) > 3.0
