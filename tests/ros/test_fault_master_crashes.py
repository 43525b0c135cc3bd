"""Two master crashes a moment apart: the second aims at the moment after the teleop guard has restarted the
mux for the first and the new mux has registered, before the guard roslaunch respawned has read
its own parameters (it reads them from the empty new master). The mux must be found again all the same: the guard
takes what its predecessor knew from their roslaunch's file. (The convergence property test
found the mux left unregistered this way; the moment is hit only now and then, so this test
guards the sequence, the property test the timing.)"""
from pathlib import Path

from testkit.real_robot import node_pid
from testkit.ros_harness import wait_until
from testkit.roscore_restart import restart_roscore


def test_the_mux_comes_back_after_two_master_crashes_a_moment_apart(ros_master):
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.wait_for_service("/mux/select", timeout=60)
    ros_master.wait_for_node("/teleop_master_guard", timeout=60)
    guard = wait_until(lambda: node_pid(ros_master, "/teleop_master_guard"), 30, "no guard")
    mux = node_pid(ros_master, "/mux")
    wait_until(lambda: any(Path(ros_master.workdir / "ros_home").glob("master_restart_guard_teleop*.json")), 30,
               "the guard kept nothing")
    restart_roscore(ros_master)
    # The guard stops the mux for roslaunch to respawn it, and ends; crash again as soon as the new
    # mux has registered, while the guard roslaunch respawns beside it is still starting.
    wait_until(lambda: not Path(f"/proc/{guard}").exists() and node_pid(ros_master, "/mux") not in (None, mux),
               30, "the guard never restarted the mux", interval=0.01)
    restart_roscore(ros_master)
    ros_master.wait_for_node("/mux", timeout=60)
    ros_master.wait_for_service("/mux/select", timeout=60)
    assert ros_master.probe.call("/mux/select", {"topic": "key_vel"}, timeout=30)["prev_topic"] == "/nav_vel"
