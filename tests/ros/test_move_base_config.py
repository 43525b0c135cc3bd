"""The shipped navigation configuration, as the nodes read it, and the message conversions."""
import math
import subprocess

import numpy as np
import pytest
import yaml

from testkit.ros_harness import PRIME_ROS
from turtlebot3c_common.message_fields import pose_from_msg
from turtlebot3c_common.ros_messages import pose_msg
from turtlebot3c_description.models import MODEL_NAMES, get_model
from turtlebot3c_navigation.costmap import INSCRIBED, LETHAL, NO_INFORMATION
from turtlebot3c_navigation.navigation_msgs import costs_to_occupancy, path_msg
from turtlebot3c_navigation.navigation_stack import amcl_params, move_base_config

CONFIG = PRIME_ROS / "share" / "turtlebot3c_navigation" / "config"


def shipped(name):
    return yaml.safe_load((CONFIG / name).read_text())


@pytest.mark.parametrize("model_name", MODEL_NAMES)
def test_shipped_move_base_config_keeps_upstream_tolerances_within_the_model_limits(model_name):
    model = get_model(model_name)
    config = move_base_config(shipped(f"move_base_{model_name}.yaml"), model)
    assert (config.dwa.xy_goal_tolerance, config.dwa.yaw_goal_tolerance) == (0.05, 0.17)
    upstream_max_vel_x = 0.22 if model_name == "burger" else 0.26
    assert config.dwa.max_vel_x == pytest.approx(min(model.max_linear_velocity, upstream_max_vel_x))
    assert config.dwa.min_vel_x == pytest.approx(-config.dwa.max_vel_x)  # upstream: it may drive backwards
    assert config.dwa.max_vel_theta <= model.max_angular_velocity
    assert config.dwa.controller_frequency == 20.0  # upstream 10: twice as often reaches goals sooner
    assert (config.nav.planner_patience, config.nav.controller_patience) == (5.0, 15.0)
    assert (config.costmap.inflation_radius, config.costmap.cost_scaling_factor) == (1.0, 3.0)
    assert config.costmap.robot_radius == pytest.approx(math.hypot(*model.footprint[0]))


def test_speeds_above_the_firmware_limit_are_clamped_and_unrelated_keys_ignored():
    model = get_model("burger")
    config = move_base_config({"DWAPlannerROS": {"max_vel_x": 5.0, "max_vel_theta": 50.0}, "global_frame": "map",
                               "planner_frequency": 2}, model)
    assert config.dwa.max_vel_x == pytest.approx(model.max_linear_velocity)
    assert config.dwa.max_vel_theta == pytest.approx(model.max_angular_velocity)
    assert config.nav.planner_frequency == 2.0


@pytest.mark.parametrize("values, expected", [
    ({"DWAPlannerROS": {"max_vel_x": float("nan")}}, "DWAPlannerROS/max_vel_x must be a finite number, got nan"),
    ({"recovery_behavior_enabled": "false"}, "recovery_behavior_enabled must be true or false, got 'false'"),
    ({"planner_frequency": "2"}, "planner_frequency must be a finite number, got '2'"),
    ({"controller_frequency": 10 ** 400}, "controller_frequency must be a finite number, got 1000"),
    ({"planner": {"cost_weight": None}}, "planner/cost_weight must be a finite number, got None"),
])
def test_a_move_base_value_of_the_wrong_kind_is_refused_in_one_line(values, expected):
    # NaN passed the speed clamps (min(nan, limit) is nan), and bool("false") is True.
    with pytest.raises(ValueError, match="move_base parameter " + expected):
        move_base_config(values, get_model("burger"))


@pytest.mark.parametrize("move_forward_only, min_vel_x", [(None, -0.26), ("false", -0.26), ("true", 0.0)])
def test_move_forward_only_keeps_move_base_from_driving_backwards_as_upstream(ros_env, move_forward_only, min_vel_x):
    args = ["model:=waffle_pi"] + ([f"move_forward_only:={move_forward_only}"] if move_forward_only else [])
    command = ["roslaunch", "--dump-params", "turtlebot3c_navigation", "turtlebot3c_navigation.launch", *args]
    dumped = subprocess.run(command, env=ros_env, capture_output=True, text=True, check=True).stdout
    assert yaml.safe_load(dumped)["/move_base/DWAPlannerROS/min_vel_x"] == min_vel_x


def test_shipped_amcl_config_has_turtlebot3_navigation_values():
    params = amcl_params(shipped("amcl.yaml"))
    assert (params.min_particles, params.max_particles, params.kld_err) == (500, 3000, 0.02)
    assert (params.update_min_d, params.update_min_a) == (0.2, 0.2)
    assert (params.odom_alpha1, params.odom_alpha2, params.odom_alpha3, params.odom_alpha4) == (0.1, 0.1, 0.1, 0.1)
    assert (params.laser_max_beams, params.laser_sigma_hit, params.laser_likelihood_max_dist) == (180, 0.2, 2.0)


def test_costs_show_in_rviz_as_costmap_2d_shows_them():
    costs = np.array([0, 1, 128, 252, INSCRIBED, LETHAL, NO_INFORMATION], dtype=np.uint8)
    assert costs_to_occupancy(costs).tolist() == [0, 1, 50, 98, 99, 100, -1]


def test_poses_and_paths_convert_both_ways():
    assert pose_from_msg(pose_msg(1.0, -2.0, 3.0)) == pytest.approx((1.0, -2.0, 3.0))
    path = path_msg(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]), "map", 0)
    assert path.header.frame_id == "map"
    assert [pose_from_msg(stamped.pose)[:2] for stamped in path.poses] == [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)]
    assert pose_from_msg(path.poses[-1].pose)[2] == pytest.approx(math.pi / 2)
