"""The controller's turns on the spot (onto the path, and to the goal heading at the end),
driven against a robot whose angular speed ramps at the model's acceleration limit."""
import math

import numpy as np
import pytest

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.dwa import DwaController, dwa_params_for_model

PERIOD = 0.05  # s, the controller frequency of the shipped configs (20 Hz)
SUBSTEP = 0.01


def ramp(current, target, acceleration, dt):
    """Angular speed after dt towards target at no more than acceleration, and the angle turned."""
    change = max(-acceleration * dt, min(acceleration * dt, target - current))
    return current + change, (2.0 * current + change) / 2.0 * dt


def controller_at_goal(model, goal_yaw):
    """A controller whose robot stands on the goal position: all that is left is the turn."""
    controller = DwaController(dwa_params_for_model(model))
    controller.set_plan(np.array([[0.0, 0.0], [0.01, 0.0]]), (0.0, 0.0, goal_yaw))
    return controller


def turn_to(model, goal_yaw, angular=0.0):
    """Drive the controller's align turn from heading 0; (seconds, commands, resting yaw)."""
    controller = controller_at_goal(model, goal_yaw)
    acceleration = model.max_angular_acceleration
    yaw, elapsed, commands = 0.0, 0.0, []
    while elapsed < 10.0:
        command = controller.compute((0.0, 0.0, yaw), (0.0, angular), None)
        commands.append(command)
        if command.status == "arrived":
            break
        for _ in range(int(round(PERIOD / SUBSTEP))):
            angular, turned = ramp(angular, command.angular, acceleration, SUBSTEP)
            yaw += turned
        elapsed += PERIOD
    while abs(angular) > 1e-9:  # the robot brakes to rest after the last command
        angular, turned = ramp(angular, 0.0, acceleration, SUBSTEP)
        yaw += turned
    return elapsed, commands, yaw


def quickest_turn(angle, max_speed, acceleration):
    """Bang-bang time for a turn from rest to rest."""
    if angle * acceleration <= max_speed ** 2:
        return 2.0 * math.sqrt(angle / acceleration)
    return angle / max_speed + max_speed / acceleration


@pytest.mark.parametrize("model_name", ["burger", "waffle_pi"])
@pytest.mark.parametrize("goal_yaw", [0.3, -1.2, 2.0, -3.0])
def test_turn_to_the_goal_heading_stays_within_the_limits_and_rests_inside_half_the_tolerance(model_name, goal_yaw):
    model = get_model(model_name)
    elapsed, commands, resting_yaw = turn_to(model, goal_yaw)
    assert commands[-1].status == "arrived"
    assert all(abs(command.linear) == 0.0 for command in commands)
    assert max(abs(command.angular) for command in commands) <= model.max_angular_velocity + 1e-9
    assert abs(resting_yaw - goal_yaw) <= 0.5 * 0.17
    # Within a few control periods of the quickest possible turn (the controller decides only every period).
    assert elapsed <= quickest_turn(abs(goal_yaw), model.max_angular_velocity, model.max_angular_acceleration) + 0.4


def test_turn_on_the_spot_uses_the_full_angular_speed_limit_on_a_long_turn():
    model = get_model("waffle_pi")
    _, commands, _ = turn_to(model, 3.0)
    assert max(abs(command.angular) for command in commands) == pytest.approx(model.max_angular_velocity)


def test_goal_is_arrived_at_while_still_turning_when_braking_now_ends_inside_the_tolerance():
    model = get_model("waffle_pi")
    controller = controller_at_goal(model, 0.12)
    # Turning towards the goal heading at 0.8 rad/s, braking now turns it a further 0.1 rad: it rests 0.02 rad off.
    assert controller.compute((0.0, 0.0, 0.0), (0.0, 0.8), None).status == "arrived"


def test_goal_is_not_arrived_at_when_the_robot_would_rest_outside_half_the_tolerance():
    model = get_model("waffle_pi")
    standing = controller_at_goal(model, 0.12).compute((0.0, 0.0, 0.0), (0.0, 0.0), None)
    turning_away = controller_at_goal(model, 0.12).compute((0.0, 0.0, 0.0), (0.0, -0.8), None)
    overshooting = controller_at_goal(model, 0.12).compute((0.0, 0.0, 0.0), (0.0, 1.8), None)
    assert (standing.status, turning_away.status, overshooting.status) == ("align", "align", "align")
    assert standing.angular > 0.0 and turning_away.angular > 0.0
    assert overshooting.angular < 0.5 * 1.8  # it would rest 0.39 rad past the heading: it brakes hard
