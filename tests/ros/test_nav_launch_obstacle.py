"""Navigation through roslaunch around an obstacle that the map does not have: the
simulator's world has a box in the gap the plan first goes through."""
import math

import pytest
import yaml

from testkit.nav_launch import RESULT, SUCCEEDED, launch_navigation, pose_stamped, true_pose
from turtlebot3c_sim.world import find_world_file

BOX = {"type": "box", "center": [-1.1, -0.55], "size": [0.3, 0.3]}


@pytest.fixture(scope="module")
def navigation_with_a_new_box(ros_master):
    description = yaml.safe_load(find_world_file("turtlebot3_world").read_text())
    description["obstacles"].append(BOX)
    world_file = ros_master.workdir / "world_with_box.yaml"
    world_file.write_text(yaml.safe_dump(description))
    return launch_navigation(ros_master, world_file)  # the map is the world without the box


def test_an_obstacle_missing_from_the_map_is_driven_around_without_collision(navigation_with_a_new_box):
    probe = navigation_with_a_new_box.probe
    probe.subscribe("/move_base/result", RESULT)
    probe.subscribe("/sim/ground_truth", "nav_msgs/Odometry")
    start = probe.count("/move_base/result")
    truth_start = probe.count("/sim/ground_truth")
    goal = (0.55, -0.55, 0.0)
    probe.publish("/move_base_simple/goal", "geometry_msgs/PoseStamped", pose_stamped(*goal))
    result = probe.wait_for_message("/move_base/result", RESULT, timeout=180, start=start)
    assert (result["status"]["status"], result["status"]["text"]) == (SUCCEEDED, "goal reached")
    x, y, _ = true_pose(probe)
    assert math.hypot(x - goal[0], y - goal[1]) < 0.08
    assert probe.wait_for_message("/sim/collisions", "std_msgs/UInt32", start=0)["data"] == 0
    # It went round a pillar instead of through the closed gap between the first two.
    driven = [(m["pose"]["pose"]["position"]["x"], m["pose"]["pose"]["position"]["y"])
              for m in probe.messages("/sim/ground_truth", truth_start)]
    assert not any(-1.4 < px < -0.8 and -0.8 < py < -0.3 for px, py in driven)
    assert max(abs(py + 0.55) for _, py in driven) > 0.4
