"""Which way the controller drives a plan (backwards when that spares turning on the spot,
as turtlebot3_navigation's min_vel_x < 0 allows), and its approach to a goal."""
import numpy as np
import pytest

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.costmap import Costmap
from turtlebot3c_navigation.dwa import DwaController, dwa_params_for_model
from turtlebot3c_navigation.grid_info import GridInfo

MODEL = get_model("waffle_pi")
FREQUENCY = 20.0  # Hz, the shipped configs' controller_frequency
GRID = GridInfo(resolution=0.05, width=120, height=120, origin_x=-3.0, origin_y=-3.0)


def open_floor(*walls_x):
    """A free 6 m square with, for each x given, a wall across it there."""
    occupied = np.zeros((GRID.height, GRID.width), bool)
    for x in walls_x:
        occupied[:, GRID.world_to_cell(np.array([x]), np.array([0.0]))[1][0]] = True
    return Costmap(GRID, occupied, robot_radius=0.2)


def straight_plan(start_x, goal_x):
    """A plan along the x axis, a point every 5 cm, as the global planner spaces them."""
    count = int(round(abs(goal_x - start_x) / 0.05)) + 1
    return np.stack([np.linspace(start_x, goal_x, count), np.zeros(count)], axis=1)


def first_command(goal_x, goal_yaw, velocity=(0.0, 0.0), **overrides):
    """The controller's command for a robot at the origin facing +x, `goal_x` along the x axis."""
    controller = DwaController(dwa_params_for_model(MODEL, **overrides))
    controller.set_plan(straight_plan(0.0, goal_x), (goal_x, 0.0, goal_yaw))
    return controller, controller.compute((0.0, 0.0, 0.0), velocity, open_floor())


def test_a_goal_behind_facing_the_robots_way_is_driven_to_backwards():
    controller, command = first_command(-1.0, 0.0)
    assert controller.direction == -1
    assert command.status == "follow" and command.linear < 0.0


def test_a_goal_behind_facing_the_other_way_is_driven_to_forwards_after_a_turn():
    controller, command = first_command(-1.0, np.pi)
    assert controller.direction == 1
    assert command.status == "rotate" and command.linear == 0.0


def test_a_goal_ahead_is_driven_to_forwards_whatever_its_heading():
    for goal_yaw in (0.0, 1.5, np.pi):
        controller, command = first_command(1.0, goal_yaw)
        assert controller.direction == 1
        assert command.linear > 0.0


def test_move_forward_only_never_drives_backwards():
    controller, command = first_command(-1.0, 0.0, min_vel_x=0.0)
    assert controller.direction == 1
    assert command.status == "rotate" and command.linear == 0.0


def test_a_robot_already_moving_keeps_its_direction_for_a_new_goal():
    controller, command = first_command(-1.0, 0.0, velocity=(0.2, 0.0))
    assert controller.direction == 1
    assert command.linear >= 0.0


def test_the_direction_is_kept_over_replans_and_chosen_again_for_a_new_goal():
    controller, _ = first_command(-1.0, 0.0)
    controller.set_plan(straight_plan(-0.1, -1.0), (-1.0, 0.0, 0.0))  # the same goal, replanned
    assert controller.direction == -1
    controller.set_plan(straight_plan(0.0, 1.0), (1.0, 0.0, 0.0))
    command = controller.compute((0.0, 0.0, 0.0), (0.0, 0.0), open_floor())
    assert controller.direction == 1 and command.linear > 0.0


def test_backwards_the_speed_limit_is_min_vel_x():
    controller = DwaController(dwa_params_for_model(MODEL, min_vel_x=-0.1))
    controller.set_plan(straight_plan(0.0, -2.0), (-2.0, 0.0, 0.0))
    velocity = (0.0, 0.0)
    for _ in range(20):
        command = controller.compute((0.0, 0.0, 0.0), velocity, open_floor())
        velocity = (command.linear, command.angular)
    assert velocity[0] == pytest.approx(-0.1)


def approach_speeds(goal_x, floor):
    """Commanded speeds driving straight at full speed towards a goal on the x axis, from
    0.4 m before it until it is reached, the robot doing exactly as commanded."""
    controller = DwaController(dwa_params_for_model(MODEL, controller_frequency=FREQUENCY))
    controller.set_plan(straight_plan(0.0, goal_x), (goal_x, 0.0, 0.0))
    x, speed, speeds = goal_x - 0.4, MODEL.max_linear_velocity, []
    while not controller.xy_reached and len(speeds) < 100:
        command = controller.compute((x, 0.0, 0.0), (speed, 0.0), floor)
        if command.status != "approach":
            break
        speeds.append(command.linear)
        speed = command.linear
        x += speed / FREQUENCY
    return speeds


@pytest.mark.parametrize("wall_behind", [None, 0.25])
def test_a_goal_is_approached_at_full_speed_until_the_braking_distance_even_before_a_wall(wall_behind):
    goal_x = 1.0
    floor = open_floor() if wall_behind is None else open_floor(goal_x + wall_behind)
    speeds = approach_speeds(goal_x, floor)
    # The braking distance at 1 m/s^2 is a few centimetres: the first 0.3 m at full speed.
    full_speed_steps = int(0.3 / (MODEL.max_linear_velocity / FREQUENCY))
    assert speeds[:full_speed_steps] == pytest.approx([MODEL.max_linear_velocity] * full_speed_steps, abs=0.01)
