"""turtlebot3c_bringup.launch with simulation:=false, from the install space, against the fake robot.

The fake robot (simulation + fake OpenCR + fake LIDAR on ptys, turtlebot3c_sim)
stands in for the hardware; its control socket pulls cables and injects faults.
"""
import math
import os
import signal
import time

import pytest

from testkit.real_robot import drive, latest_odometry, node_pid, start_robot
from testkit.ros_harness import wait_until
from turtlebot3c_sim.fake_robot import send_command

ODOMETRY = "nav_msgs/Odometry"
SCAN = "sensor_msgs/LaserScan"
JOINTS = "sensor_msgs/JointState"
TWIST = "geometry_msgs/Twist"
DIAGNOSTICS = "diagnostic_msgs/DiagnosticArray"


@pytest.fixture(scope="module")
def robot(ros_master):
    control = start_robot(ros_master, "waffle_pi", "LDS-01")
    ros_master.wait_for_node("/robot_state_publisher", timeout=60)
    ros_master.probe.wait_for_message("/odom", ODOMETRY, timeout=60)
    return ros_master, control


def test_odometry_scan_joint_states_and_tf_are_published(robot):
    master, _ = robot
    probe = master.probe
    odom = probe.wait_for_message("/odom", ODOMETRY)
    assert (odom["header"]["frame_id"], odom["child_frame_id"]) == ("odom", "base_footprint")
    scan = probe.wait_for_message("/scan", SCAN, timeout=30)
    assert scan["header"]["frame_id"] == "base_scan"
    assert len(scan["ranges"]) == 360
    assert scan["angle_min"] == 0.0 and scan["angle_increment"] == pytest.approx(2 * math.pi / 360)
    assert (scan["range_min"], scan["range_max"]) == (pytest.approx(0.12), pytest.approx(3.5))
    assert sum(1 for value in scan["ranges"] if 0.12 <= value <= 3.5) > 100  # turtlebot3_world has walls around
    joints = probe.wait_for_message("/joint_states", JOINTS)
    assert joints["name"] == ["wheel_left_joint", "wheel_right_joint"]
    imu = probe.wait_for_message("/imu", "sensor_msgs/Imu")
    assert imu["header"]["frame_id"] == "imu_link"
    assert imu["linear_acceleration"]["z"] == pytest.approx(9.8, abs=0.3)
    battery = probe.wait_for_message("/battery_state", "sensor_msgs/BatteryState")
    assert battery["voltage"] == pytest.approx(12.0) and battery["present"]
    assert 0.0 <= battery["percentage"] <= 1.0
    buttons = probe.wait_for_message("/buttons", "sensor_msgs/Joy", start=0)  # latched
    assert buttons["buttons"] == [0, 0, 0, 0]
    assert "/turtlebot3_core" in master.publishers("/tf")
    assert "/robot_state_publisher" in master.node_names()
    assert master.param("/robot_description").count("turtlebot3_waffle_pi") >= 1


def test_the_tf_tree_joins_odometry_and_the_robot_model(robot):
    master, _ = robot
    scan_in_odom = master.probe.transform("odom", "base_scan", timeout=10)["transform"]["translation"]
    base_in_odom = master.probe.transform("odom", "base_footprint", timeout=10)["transform"]["translation"]
    assert scan_in_odom["z"] == pytest.approx(0.132, abs=1e-6)  # scan_joint 0.122 above base_link, +0.010
    assert math.hypot(scan_in_odom["x"] - base_in_odom["x"], scan_in_odom["y"] - base_in_odom["y"]) == \
        pytest.approx(0.064, abs=1e-3)
    wheel = master.probe.transform("base_link", "wheel_left_link", timeout=10)["transform"]["translation"]
    assert wheel["y"] == pytest.approx(0.144)


def test_cmd_vel_moves_the_fake_robot_and_odometry_follows(robot):
    master, control = robot
    probe = master.probe
    true_start = send_command(control, "pose")
    odom_start = latest_odometry(probe)["position"]
    drive(probe, 0.15, 0.0, 2.0)
    wait_until(lambda: send_command(control, "status")["velocity"][0] == 0.0, 5,
               "the fake robot kept moving after /cmd_vel went silent")
    true_end = send_command(control, "pose")
    odom_end = latest_odometry(probe)["position"]
    true_travel = math.hypot(true_end[0] - true_start[0], true_end[1] - true_start[1])
    odom_travel = math.hypot(odom_end["x"] - odom_start["x"], odom_end["y"] - odom_start["y"])
    assert true_travel > 0.2
    assert odom_travel == pytest.approx(true_travel, abs=0.02)


def test_unplugged_opencr_stops_odometry_and_replug_resumes_without_a_jump(robot):
    master, control = robot
    probe = master.probe
    before = latest_odometry(probe)["position"]
    send_command(control, "unplug opencr")
    probe.subscribe("/diagnostics", DIAGNOSTICS)

    def link_error_reported():
        return any(status["name"] == "turtlebot3c: OpenCR link" and status["level"] == 2
                   for array in probe.messages("/diagnostics") for status in array["status"])
    wait_until(link_error_reported, 10, "no diagnostics error for the unplugged OpenCR")
    quiet_from = probe.count("/odom")
    time.sleep(1.0)
    assert probe.count("/odom") == quiet_from, "odometry published while the OpenCR was unplugged"
    send_command(control, "replug opencr")
    resumed = probe.wait_for_message("/odom", ODOMETRY, timeout=10)["pose"]["pose"]["position"]
    assert math.hypot(resumed["x"] - before["x"], resumed["y"] - before["y"]) < 0.02
    drive(probe, 0.1, 0.0, 1.0)  # and the robot obeys again
    wait_until(lambda: abs(send_command(control, "status")["velocity"][0]) < 1e-9, 5, "robot did not stop")
    moved = latest_odometry(probe)["position"]
    assert math.hypot(moved["x"] - resumed["x"], moved["y"] - resumed["y"]) > 0.05


def test_corrupted_frames_are_survived_and_counted(robot):
    master, control = robot
    probe = master.probe
    send_command(control, "faults opencr crc=0.2,garbage=0.1,truncate=0.05")
    send_command(control, "faults lds garbage=0.2,checksum=0.1,truncate=0.05")
    try:
        odom_start, scan_start = probe.count("/odom"), probe.count("/scan")
        probe.subscribe("/scan", SCAN)
        time.sleep(3.0)
        assert probe.count("/odom") - odom_start > 30
        assert probe.count("/scan") - scan_start > 5
    finally:
        send_command(control, "faults opencr none")
        send_command(control, "faults lds none")

    def error_counts():
        counts = {}
        for array in probe.messages("/diagnostics"):
            for status in array["status"]:
                for pair in status["values"]:
                    counts[(status["name"], pair["key"])] = pair["value"]
        return counts
    probe.subscribe("/diagnostics", DIAGNOSTICS)
    wait_until(lambda: int(error_counts().get(("turtlebot3c: OpenCR link", "communication errors"), 0)) > 0, 5,
               "no OpenCR communication errors counted")
    wait_until(lambda: int(error_counts().get(("turtlebot3c: LIDAR (LDS-01)", "bytes discarded"), 0)) > 0, 5,
               "no discarded LIDAR bytes counted")
    assert {"/turtlebot3_core", "/turtlebot3_lds"} <= master.node_names()


def test_unplugged_lidar_is_reopened(robot):
    master, control = robot
    probe = master.probe
    probe.subscribe("/scan", SCAN)
    send_command(control, "unplug lds")
    time.sleep(1.0)
    quiet_from = probe.count("/scan")
    time.sleep(0.6)
    assert probe.count("/scan") == quiet_from
    send_command(control, "replug lds")
    probe.wait_for_message("/scan", SCAN, timeout=10)


def test_lds02_burger_bringup_gives_the_same_scan_layout(make_master):
    master = make_master()
    start_robot(master, "burger", "LDS-02")
    scan = master.probe.wait_for_message("/scan", SCAN, timeout=60)
    assert scan["header"]["frame_id"] == "base_scan"
    assert len(scan["ranges"]) == 360 and scan["angle_min"] == 0.0
    assert (scan["range_min"], scan["range_max"]) == (pytest.approx(0.16), pytest.approx(8.0))
    assert sum(1 for value in scan["ranges"] if 0.16 <= value <= 3.5) > 100
    master.probe.wait_for_message("/odom", ODOMETRY, timeout=30)
    assert "turtlebot3_burger" in master.param("/robot_description")


def test_a_killed_driver_is_respawned_and_its_odometry_continues(robot):
    master, _ = robot
    probe = master.probe
    drive(probe, 0.1, 0.5, 1.0)  # somewhere away from the odometry's origin
    time.sleep(1.0)  # the save (5 Hz) has the pose the robot stopped at
    before = latest_odometry(probe)["position"]
    assert math.hypot(before["x"], before["y"]) > 0.05
    pid = node_pid(master, "/turtlebot3_core")
    assert pid
    os.kill(pid, signal.SIGKILL)
    wait_until(lambda: node_pid(master, "/turtlebot3_core") not in (None, pid), 30, "turtlebot3_core not respawned")
    after = probe.wait_for_message("/odom", ODOMETRY, timeout=30)["pose"]["pose"]["position"]
    assert math.hypot(after["x"] - before["x"], after["y"] - before["y"]) < 0.01


@pytest.mark.parametrize("executable, parameter, value, known", [
    ("opencr_driver", "_model", "tractor", "burger, waffle, waffle_pi"),
    ("lds_driver", "_lds_model", "LDS-03", "LDS-01, LDS-02"),
])
def test_an_unknown_model_stops_the_driver_with_the_known_ones(robot, executable, parameter, value, known):
    master, _ = robot
    driver = master.rosrun("turtlebot3c_bringup", executable, f"__name:=bad_{executable}", f"{parameter}:={value}")
    wait_until(lambda: not driver.running(), 30, f"{executable} kept running with {value}")
    assert driver.popen.returncode != 0
    assert value in driver.log_text() and known in driver.log_text()


@pytest.mark.parametrize("package, executable, parameter, expected", [
    # Infinite or not a number, the timeouts would never stop a robot whose commands stopped.
    ("turtlebot3c_bringup", "opencr_driver", "_command_timeout:=.inf", "~command_timeout must be a finite number"),
    ("turtlebot3c_teleop", "velocity_watchdog", "_timeout:=.nan", "~timeout must be a finite number"),
    ("turtlebot3c_bringup", "lds_driver", "_range_max:=-1.0", "~range_max must be more than 0, got -1.0"),
    ("turtlebot3c_bringup", "opencr_driver", "_publish_tf:=maybe", "~publish_tf must be true or false, got 'maybe'"),
])
def test_a_parameter_the_node_cannot_run_with_stops_it_with_one_line(robot, package, executable, parameter, expected):
    master, _ = robot
    status, log = master.rosrun_refused(package, executable, parameter)
    assert status != 0
    assert expected in log and "Traceback" not in log
