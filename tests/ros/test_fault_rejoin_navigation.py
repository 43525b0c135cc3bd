"""A roscore killed and restarted while navigating: map_server, amcl and move_base register again in process.

The simulator, the robot model (bringup simulation:=true), the teleop mux and the navigation
launch run on a map of turtlebot3_world; the roscore is SIGKILLed and a new one started on the
same port. New subscribers and action clients must find the same navigation processes, amcl
must still know where the robot is, and a goal sent after the restart must be reached (through
the mux, which the teleop guard restarted).
"""
import math
import time

import numpy as np
import pytest

from testkit.nav_launch import GROUND_TRUTH, RESULT, SPAWN, SUCCEEDED, launch_navigation, pose_stamped, true_pose
from testkit.real_robot import node_pid
from testkit.ros_harness import wait_until
from testkit.roscore_restart import restart_roscore

POSE = "geometry_msgs/PoseWithCovarianceStamped"
NAVIGATION_NODES = ("/map_server", "/amcl", "/move_base")
GOAL_ACROSS = (1.8, 0.5, 0.0)  # sent before the restart, reached after it: across the world, so that
# the drive (about 20 s) outlasts a restart slowed down by a loaded machine
GOAL_AFTER = (-1.8, -0.5, math.pi)


def true_position(probe):
    return true_pose(probe, timeout=30)[:2]


def localisation_error(probe, estimate):
    """How far amcl's `estimate` is from where the simulated robot truly was at the estimate's time."""
    stamp = estimate["header"]["stamp"]
    truth = min(probe.messages("/sim/ground_truth"), key=lambda message: abs(message["header"]["stamp"] - stamp))
    assert abs(truth["header"]["stamp"] - stamp) < 0.1, "no ground truth from the estimate's time"
    guess, true = estimate["pose"]["pose"]["position"], truth["pose"]["pose"]["position"]
    return math.hypot(guess["x"] - true["x"], guess["y"] - true["y"])


@pytest.fixture(scope="module")
def navigation(ros_master):
    """Navigation localised at the spawn pose, driving to a goal when the roscore is restarted; the pids before."""
    launch_navigation(ros_master)
    probe = ros_master.probe
    pids = {name: node_pid(ros_master, name) for name in NAVIGATION_NODES}
    send_goal(probe, "across-the-restart", GOAL_ACROSS)
    wait_until(lambda: math.hypot(*np.subtract(true_position(probe), SPAWN[:2])) > 0.1, 60, "the robot never set off")
    restart_roscore(ros_master)
    ros_master.probe.subscribe("/move_base/result", RESULT)  # from now: the goal's result may come any time
    ros_master.probe.subscribe("/sim/ground_truth", GROUND_TRUTH)
    return {"master": ros_master, "pids": pids, "watched": time.time()}


def send_goal(probe, name, pose):
    probe.publish("/move_base/goal", "move_base_msgs/MoveBaseActionGoal",  # as an action client does
                  {"goal_id": {"id": name}, "goal": {"target_pose": pose_stamped(*pose)}}, latch=True)


def wait_for_result(probe, name, timeout=180):
    result = probe.wait_for_message("/move_base/result", RESULT, timeout=timeout, start=0,
                                    where=lambda result: result["status"]["goal_id"]["id"] == name)
    return result["status"]["status"]


def test_the_same_navigation_nodes_are_found_again_with_their_map_and_pose(navigation):
    master = navigation["master"]
    for node in NAVIGATION_NODES + ("/mux", "/simulator"):
        master.wait_for_node(node, timeout=60)
    assert {name: node_pid(master, name) for name in NAVIGATION_NODES} == navigation["pids"], "a node was restarted"
    probe = master.probe
    grid = probe.wait_for_message("/map", "nav_msgs/OccupancyGrid", timeout=30, start=0)  # latched by map_server
    assert probe.call("/static_map", timeout=30)["map"]["info"]["width"] == grid["info"]["width"]
    # The probe's ground-truth subscription connects some time after the restart: judge an
    # estimate made once the truth is arriving, so the two can be compared at the same time.
    truth = probe.wait_for_message("/sim/ground_truth", GROUND_TRUTH, timeout=30, start=0)
    since = max(navigation["watched"], truth["header"]["stamp"])
    estimate = probe.wait_for_message("/amcl_pose", POSE, timeout=60, start=0,
                                      where=lambda pose: pose["header"]["stamp"] > since)
    assert localisation_error(probe, estimate) < 0.15  # amcl kept its particles and takes scans again
    assert master.param("/amcl/initial_pose_x") == SPAWN[0]  # its private parameters are back
    probe.wait_for_message("/move_base/status", "actionlib_msgs/GoalStatusArray", timeout=30)


def test_the_goal_being_driven_to_across_the_restart_is_reached(navigation):
    probe = navigation["master"].probe
    assert wait_for_result(probe, "across-the-restart") == SUCCEEDED  # move_base kept it; the new mux passes it on
    x, y = true_position(probe)
    assert math.hypot(x - GOAL_ACROSS[0], y - GOAL_ACROSS[1]) < 0.1


def test_a_goal_sent_after_the_restart_is_reached(navigation):
    master = navigation["master"]
    master.wait_for_node("/move_base", timeout=60)
    probe = master.probe
    wait_for_result(probe, "across-the-restart")
    probe.subscribe("/amcl_pose", POSE)
    sent = time.time()
    send_goal(probe, "after-the-restart", GOAL_AFTER)
    assert wait_for_result(probe, "after-the-restart") == SUCCEEDED
    x, y = true_position(probe)
    assert math.hypot(x - GOAL_AFTER[0], y - GOAL_AFTER[1]) < 0.1
    latest = probe.messages("/amcl_pose")[-1]
    assert latest["header"]["stamp"] > sent, "amcl took no scan on the way"
    assert localisation_error(probe, latest) < 0.15
