"""turtlebot3c_navigation.launch end to end, from the install space: the simulator, the
model (bringup simulation:=true), the teleop mux and navigation on a map of the world."""
import math

import numpy as np
import pytest

from ros_harness import wait_until
from turtlebot3c_2dnav.map_files import OccupancyMap, save_map
from turtlebot3c_2dnav.navigation_loop import world_layers
from turtlebot3c_sim.world import load_world

RESULT = "move_base_msgs/MoveBaseActionResult"
GROUND_TRUTH = "nav_msgs/Odometry"
SUCCEEDED, ABORTED = 3, 4
SPAWN = (-2.0, -0.5, 0.0)


def write_world_map(folder):
    layers = world_layers(load_world("turtlebot3_world"))
    data = np.where(layers.occupied, 100, 0)
    folder.mkdir(parents=True, exist_ok=True)
    yaml_path, _ = save_map(OccupancyMap(data, layers.info.resolution, (layers.info.origin_x, layers.info.origin_y, 0)),
                            folder / "current_map")
    return yaml_path


@pytest.fixture(scope="module")
def navigation(ros_master):
    map_file = write_world_map(ros_master.workdir / "map")
    ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "model:=burger")
    ros_master.launch("turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=true", "model:=burger")
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.launch("turtlebot3c_2dnav", "turtlebot3c_navigation.launch", "model:=burger", f"map_file:={map_file}",
                      f"initial_pose_x:={SPAWN[0]}", f"initial_pose_y:={SPAWN[1]}", f"initial_pose_a:={SPAWN[2]}")
    for node in ("/map_server", "/amcl", "/move_base", "/mux", "/simulator"):
        ros_master.wait_for_node(node, timeout=90)
    ros_master.probe.wait_for_message("/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped", timeout=60, start=0)
    return ros_master


def pose_stamped(x, y, yaw):
    return {"header": {"frame_id": "map"},
            "pose": {"position": {"x": x, "y": y}, "orientation": {"z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}}}


def true_pose(probe):
    message = probe.wait_for_message("/sim/ground_truth", GROUND_TRUTH, timeout=10)
    pose = message["pose"]["pose"]
    yaw = 2 * math.atan2(pose["orientation"]["z"], pose["orientation"]["w"])
    return pose["position"]["x"], pose["position"]["y"], yaw


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
    process = navigation.rosrun("turtlebot3c_2dnav", "map_server", missing, "__name:=map_server_missing")
    wait_until(lambda: not process.running(), 30, "map_server kept running without a map")
    assert process.popen.returncode != 0
    assert f"cannot read map file {missing}" in process.log_text()
