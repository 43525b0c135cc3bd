"""turtlebot3c_navigation.launch end to end, from the install space: the simulator, the
model (bringup simulation:=true), the teleop mux and navigation on a map of the world."""
import math
import time

import pytest

from testkit.nav_launch import ABORTED, RESULT, SPAWN, SUCCEEDED, launch_navigation, pose_stamped, true_pose
from testkit.ros_harness import wait_until


@pytest.fixture(scope="module")
def navigation(ros_master):
    return launch_navigation(ros_master)


def test_map_server_publishes_the_map_latched_and_answers_static_map(navigation):
    probe = navigation.probe
    grid = probe.wait_for_message("/map", "nav_msgs/OccupancyGrid", start=0)
    assert grid["header"]["frame_id"] == "map"
    assert grid["info"]["resolution"] == pytest.approx(0.05)
    assert len(grid["data"]) == grid["info"]["width"] * grid["info"]["height"]
    assert set(grid["data"]) == {0, 100}
    served = probe.call("/static_map")["map"]
    assert served["info"]["width"] == grid["info"]["width"] and served["data"] == grid["data"]


def test_amcl_localises_at_the_initial_pose_and_publishes_map_to_odom(navigation):
    probe = navigation.probe
    estimate = probe.wait_for_message("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", start=0)
    assert estimate["header"]["frame_id"] == "map"
    position = estimate["pose"]["pose"]["position"]
    assert math.hypot(position["x"] - SPAWN[0], position["y"] - SPAWN[1]) < 0.1
    transform = probe.transform("map", "odom", timeout=10)
    assert transform["header"]["frame_id"] == "map" and transform["child_frame_id"] == "odom"


def test_goal_from_rviz_is_reached_through_the_mux(navigation):
    probe = navigation.probe
    probe.subscribe("/move_base/result", RESULT)
    probe.subscribe("/move_base/plan", "nav_msgs/Path")
    start = probe.count("/move_base/result")
    plans_start = probe.count("/move_base/plan")
    goal = (-0.55, -0.55, math.pi / 2)
    probe.publish("/move_base_simple/goal", "geometry_msgs/PoseStamped", pose_stamped(*goal))
    result = probe.wait_for_message("/move_base/result", RESULT, timeout=120, start=start)
    assert (result["status"]["status"], result["status"]["text"]) == (SUCCEEDED, "goal reached")
    x, y, yaw = true_pose(probe)
    assert math.hypot(x - goal[0], y - goal[1]) < 0.08
    assert abs(math.remainder(yaw - goal[2], 2 * math.pi)) < 0.2
    first_plan = probe.messages("/move_base/plan", plans_start)[0]
    assert first_plan["header"]["frame_id"] == "map" and len(first_plan["poses"]) > 20  # 5 cm apart, > 1 m
    end = first_plan["poses"][-1]["pose"]["position"]
    assert (end["x"], end["y"]) == (pytest.approx(goal[0]), pytest.approx(goal[1]))
    collisions = probe.wait_for_message("/sim/collisions", "std_msgs/UInt32", start=0)
    assert collisions["data"] == 0


def test_a_goal_sent_as_soon_as_a_new_initial_pose_is_taken_is_planned_from_that_pose(navigation):
    # AMCL dates map -> odom half a second ahead (transform_tolerance), as ROS amcl does; a lookup at
    # the present time would still find the superseded transform for that half second.
    probe = navigation.probe
    probe.subscribe("/move_base/result", RESULT)
    probe.subscribe("/move_base/plan", "nav_msgs/Path")
    x, y, yaw = true_pose(probe)
    # A first goal where the robot stands: the probe's first publish on a topic waits for subscribers.
    start = probe.count("/move_base/result")
    probe.publish("/move_base_simple/goal", "geometry_msgs/PoseStamped", pose_stamped(x, y, yaw))
    probe.wait_for_message("/move_base/result", RESULT, timeout=60, start=start)
    x, y, yaw = true_pose(probe)
    ahead = (x + 0.4 * math.cos(yaw), y + 0.4 * math.sin(yaw), yaw)
    behind = (x - 0.5 * math.cos(yaw), y - 0.5 * math.sin(yaw), yaw)

    # Tight enough that AMCL's one update at rest cannot carry the estimate far: with 0.05 m the
    # cloud's outermost particles, 0.2 m out, sometimes took the weight and left the pose behind
    # under 0.3 m from the robot.
    tight = [0.0] * 36
    tight[0] = tight[7] = tight[35] = 0.02 ** 2

    def set_initial_pose(pose):
        """AMCL's estimate's distance from the robot once it took `pose`: at rest, it updates once
        on a new pose. An estimate of the last update before, still on its way, does not count."""
        estimates = probe.count("/amcl_pose")
        message = {"header": {"frame_id": "map"}, "pose": {"pose": pose_stamped(*pose)["pose"], "covariance": tight}}
        probe.publish("/initialpose", "geometry_msgs/PoseWithCovarianceStamped", message)
        estimate = probe.wait_for_message("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", timeout=30,
                                          start=estimates, where=lambda estimate: distance_to(estimate, pose) < 0.2)
        return distance_to(estimate, (x, y))

    assert set_initial_pose(behind) > 0.3
    time.sleep(1.0)  # AMCL's transforms dated ahead now all hold the pose behind
    assert set_initial_pose((x, y, yaw)) < 0.1
    start, plans_start = probe.count("/move_base/result"), probe.count("/move_base/plan")
    probe.publish("/move_base_simple/goal", "geometry_msgs/PoseStamped", pose_stamped(*ahead))
    first_plan = probe.wait_for_message("/move_base/plan", "nav_msgs/Path", timeout=30, start=plans_start)
    origin = first_plan["poses"][0]["pose"]["position"]
    assert math.hypot(origin["x"] - x, origin["y"] - y) < 0.15
    result = probe.wait_for_message("/move_base/result", RESULT, timeout=60, start=start)
    assert result["status"]["status"] == SUCCEEDED


def distance_to(estimate, pose):
    position = estimate["pose"]["pose"]["position"]
    return math.hypot(position["x"] - pose[0], position["y"] - pose[1])


def test_unreachable_goal_is_aborted_with_a_clear_status(navigation):
    probe = navigation.probe
    probe.subscribe("/move_base/result", RESULT)
    start = probe.count("/move_base/result")
    probe.publish("/move_base/goal", "move_base_msgs/MoveBaseActionGoal",
                  {"goal_id": {"id": "into-the-pillar"}, "goal": {"target_pose": pose_stamped(0.0, 0.0, 0.0)}})
    result = probe.wait_for_message("/move_base/result", RESULT, timeout=60, start=start)
    assert result["status"]["status"] == ABORTED
    assert result["status"]["goal_id"]["id"] == "into-the-pillar"
    assert result["status"]["text"].startswith("goal unreachable: goal (0.00, 0.00) is in or too close to an obstacle")


def test_global_localization_spreads_the_particles_over_the_map(navigation):
    probe = navigation.probe
    probe.subscribe("/particlecloud", "geometry_msgs/PoseArray")
    start = probe.count("/particlecloud")
    probe.call("/global_localization")
    cloud = probe.wait_for_message("/particlecloud", "geometry_msgs/PoseArray", timeout=30, start=start,
                                   where=lambda cloud: len(cloud["poses"]) == 3000)  # max_particles
    xs = [pose["position"]["x"] for pose in cloud["poses"]]
    ys = [pose["position"]["y"] for pose in cloud["poses"]]
    assert max(xs) - min(xs) > 5.0 and max(ys) - min(ys) > 4.0  # over the whole map
    # Give the robot its pose back for the tests that follow.
    probe.publish("/initialpose", "geometry_msgs/PoseWithCovarianceStamped",
                  {"header": {"frame_id": "map"}, "pose": {"pose": pose_stamped(*true_pose(probe))["pose"]}})


def test_map_server_without_a_map_exits_with_a_clear_message(navigation):
    missing = navigation.workdir / "no-such-map.yaml"
    process = navigation.rosrun("turtlebot3c_maps", "map_server", missing, "__name:=map_server_missing")
    wait_until(lambda: not process.running(), 30, "map_server kept running without a map")
    assert process.popen.returncode != 0
    assert f"cannot read map file {missing}" in process.log_text()


@pytest.mark.parametrize("node, parameter, expected", [
    ("amcl", "_laser_sigma_hit:=0.0", "amcl parameter laser_sigma_hit must be more than 0, got 0.0"),
    ("amcl", "_seed:=-3", "amcl parameter seed must be from 0 to 2^32 - 1, got -3"),
    ("amcl", "_seed:=abc", "amcl parameter seed must be a finite number, got 'abc'"),
    ("amcl", "_initial_pose_x:=nan", "parameter ~initial_pose_x must be a finite number, got 'nan'"),
    ("move_base", "_planner_frequency:=often", "move_base parameter planner_frequency must be a finite number"),
])
def test_a_parameter_the_node_cannot_run_with_stops_it_with_one_line(navigation, node, parameter, expected):
    status, log = navigation.rosrun_refused("turtlebot3c_navigation", node, parameter)
    assert status != 0
    assert expected in log and "Traceback" not in log
