"""Fault matrix on the real-robot path: the core and teleop daemons' launch files against the fake robot.

Cables pulled mid-drive, corrupted serial frames for a sustained period, nodes
SIGKILLed, the ROS master killed and restarted. Each case states what must
happen; `benchmarks/bench_faults` prints the figures (stop latency, reconnect time,
lost messages) over more repetitions and longer soaks.
"""
import math
import os
import signal
import time

import pytest

from testkit.real_robot import (
    CHAIN_NODES,
    DAEMON_NODES,
    ODOMETRY,
    SCAN,
    SPEED,
    KeySource,
    latest_odometry,
    node_pid,
    start_robot,
    status,
    wait_until_driving,
    watch_until_at_rest,
)
from testkit.ros_harness import wait_until
from testkit.roscore_restart import restart_roscore
from turtlebot3c_sim.fake_robot import send_command

DIAGNOSTICS = "diagnostic_msgs/DiagnosticArray"
STOP_BUDGET = 0.5  # s from the fault to motors commanded to stop
RECONNECT_BUDGET = 3.0  # s from replug to odometry again
LOAD_MARGIN = 0.3  # s a loaded test machine may add to any of these
SOAK_SECONDS = 20  # per fault rate here; benchmarks/bench_faults soaks for minutes
REJOINING_NODES = ("/turtlebot3_core", "/turtlebot3_lds", "/velocity_watchdog")  # rospy: in process


@pytest.fixture(scope="module")
def robot(ros_master):
    control = start_robot(ros_master, "burger", "LDS-01", world="empty")
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.wait_for_service("/mux/select", timeout=60)
    ros_master.probe.wait_for_message("/odom", ODOMETRY, timeout=60)
    return ros_master, control


def diagnostic_values(probe, name, start=0):
    values = {}
    for array in probe.messages("/diagnostics", start):
        for entry in array["status"]:
            if entry["name"] == name:
                values = {pair["key"]: pair["value"] for pair in entry["values"]}
    return values


def test_opencr_unplugged_mid_drive_stops_the_robot_and_replug_resumes_odometry_without_a_jump(robot):
    master, control = robot
    probe = master.probe
    source = KeySource(master)
    try:
        wait_until_driving(control)
        before = latest_odometry(probe)["position"]
        commanded = status(control)["time"]
        send_command(control, "unplug opencr")
        # The stop is timed from the board's own records, in simulated time: status polls on a
        # loaded machine would add their delays (benchmarks/bench_faults times it from the command).
        unplugged = status(control)["devices"]["opencr"]["unplugged_at"]
        _, to_rest = watch_until_at_rest(control, since=commanded)  # the odometry's last pose is from before
        stalled = status(control)["devices"]["opencr"]["stalled_at"]
        assert stalled is not None and stalled >= unplugged, "the motors stopped, but not by the board's heartbeat"
        to_zero = stalled - unplugged
        print(f"OpenCR unplugged: motors stopped after {to_zero:.3f} s, robot at rest after {to_rest:.3f} s")
        assert to_zero <= STOP_BUDGET + LOAD_MARGIN  # the board's own heartbeat timeout: nobody can write to it
        odom_count = probe.count("/odom")
        time.sleep(0.5)
        assert probe.count("/odom") == odom_count, "odometry published while the OpenCR was unplugged"
        send_command(control, "replug opencr")
        replugged_at = time.time()
        resumed = probe.wait_for_message("/odom", ODOMETRY, timeout=10)
        # The driver's stamp (wall time, at its read): the probe's receipt would add a loaded machine's delays.
        reconnect = probe.timed_messages("/odom", odom_count)[0]["msg"]["header"]["stamp"] - replugged_at
        print(f"OpenCR replugged: odometry again after {reconnect:.3f} s")
        assert reconnect <= RECONNECT_BUDGET + LOAD_MARGIN
        position = resumed["pose"]["pose"]["position"]
        # The board was reset by the replug: the wheel travel while unplugged is unknowable, not a jump.
        coasted = SPEED * (to_rest + 0.1)
        assert math.hypot(position["x"] - before["x"], position["y"] - before["y"]) <= coasted + 0.02
        truth_start = status(control)["pose"]
        wait_until_driving(control)  # the source still drives: the robot obeys again
        time.sleep(0.5)
        truth_end, odom_end = status(control)["pose"], latest_odometry(probe)["position"]
        true_travel = math.hypot(truth_end[0] - truth_start[0], truth_end[1] - truth_start[1])
        odom_travel = math.hypot(odom_end["x"] - position["x"], odom_end["y"] - position["y"])
        assert odom_travel == pytest.approx(true_travel, abs=0.05)
    finally:
        send_command(control, "replug opencr")  # whatever failed, the module's later tests get a robot
        source.kill()
    watch_until_at_rest(control)


def test_lidar_unplugged_and_replugged_resumes_scans(robot):
    master, control = robot
    probe = master.probe
    probe.wait_for_message("/scan", SCAN, timeout=10)
    send_command(control, "unplug lds")
    try:
        time.sleep(0.5)  # a scan already on its way may still arrive
        quiet_from = probe.count("/scan")
        time.sleep(1.0)
        assert probe.count("/scan") == quiet_from, "scans published while the LIDAR was unplugged"
    finally:
        send_command(control, "replug lds")  # whatever failed, the module's later tests get a robot
    replugged_at = time.time()
    probe.wait_for_message("/scan", SCAN, timeout=10, where=lambda scan: len(scan["ranges"]) == 360)
    reopened = probe.timed_messages("/scan", quiet_from)[0]["msg"]["header"]["stamp"] - replugged_at  # its first ray
    print(f"LIDAR replugged: scans again after {reopened:.3f} s")
    assert reopened <= RECONNECT_BUDGET + LOAD_MARGIN
    assert "/turtlebot3_lds" in master.node_names()


@pytest.mark.parametrize("rate", [0.01, 0.10])
def test_garbage_and_corrupt_frames_for_a_sustained_period_are_survived_and_counted(robot, rate):
    master, control = robot
    probe = master.probe
    pids = {name: node_pid(master, name) for name in ("/turtlebot3_core", "/turtlebot3_lds")}
    probe.subscribe("/diagnostics", DIAGNOSTICS)
    probe.subscribe("/scan", SCAN)
    probe.wait_for_message("/odom", ODOMETRY)
    before = status(control)["devices"]
    send_command(control, f"faults opencr crc={rate},garbage={rate}")
    send_command(control, f"faults lds garbage={rate},checksum={rate}")
    odom_start, scan_start, diagnostics_start = probe.count("/odom"), probe.count("/scan"), probe.count("/diagnostics")
    started = time.time()
    try:
        time.sleep(SOAK_SECONDS)
    finally:
        send_command(control, "faults opencr none")
        send_command(control, "faults lds none")
    elapsed = time.time() - started
    odometry = [entry["t"] for entry in probe.timed_messages("/odom", odom_start)]
    scans = probe.count("/scan") - scan_start
    gaps = [later - earlier for earlier, later in zip([started] + odometry, odometry + [time.time()])]
    after = status(control)["devices"]
    injected = {name: {kind: count - before[name]["faults_injected"][kind]
                       for kind, count in after[name]["faults_injected"].items() if count}
                for name in ("opencr", "lds")}
    print(f"{rate:.0%} corrupt frames for {elapsed:.0f} s: {len(odometry) / elapsed:.1f} odom/s (50 nominal), "
          f"{scans / elapsed:.1f} scans/s (5 nominal), longest odometry gap {max(gaps):.2f} s; injected {injected}")
    assert {name: node_pid(master, name) for name in pids} == pids, "a driver crashed and was respawned"
    assert max(gaps) < 2.5, "odometry stopped for longer than a reconnection takes"
    assert len(odometry) > 0.5 * 50 * elapsed and scans > 0.5 * 5 * elapsed
    link = diagnostic_values(probe, "turtlebot3c: OpenCR link", diagnostics_start)
    lidar = diagnostic_values(probe, "turtlebot3c: LIDAR (LDS-01)", diagnostics_start)
    assert int(link["communication errors"]) > 0, link
    assert int(lidar["bytes discarded"]) > 0, lidar


@pytest.mark.parametrize("name", DAEMON_NODES)
def test_a_sigkilled_node_is_respawned_and_the_robot_stops_meanwhile(robot, name):
    master, control = robot
    probe = master.probe
    source = KeySource(master)
    try:
        wait_until_driving(control)
        pid = node_pid(master, name)
        assert pid, f"{name} is not running"
        killed = status(control)["time"]
        os.kill(pid, signal.SIGKILL)
        if name in CHAIN_NODES:
            to_zero, to_rest = watch_until_at_rest(control, since=killed)
            print(f"{name} SIGKILLed: motors stopped after {to_zero:.3f} s, at rest after {to_rest:.3f} s")
            assert to_zero <= STOP_BUDGET + LOAD_MARGIN
        wait_until(lambda: node_pid(master, name) not in (None, pid), 30, f"{name} was not respawned")
    finally:
        source.kill()
    watch_until_at_rest(control)
    probe.wait_for_message("/odom", ODOMETRY, timeout=30)
    probe.wait_for_message("/scan", SCAN, timeout=30)
    probe.wait_for_message("/mux/selected", "std_msgs/String", start=0, timeout=30)
    assert node_pid(master, "/turtlebot3_core") and node_pid(master, "/velocity_watchdog")


def test_a_restarted_roscore_gets_every_node_and_parameter_back_without_restarting_the_launch(robot):
    """Twice: the guards respawned after the first restart watch for the next."""
    master, control = robot
    launches = [process for process in master.processes if process.name.startswith("roslaunch-")]
    before = latest_odometry(master.probe)["position"]
    rejoining = {name: node_pid(master, name) for name in REJOINING_NODES}
    restart_roscore(master)
    for name in DAEMON_NODES + ("/bringup_master_guard", "/teleop_master_guard"):
        master.wait_for_node(name, timeout=60)
    assert {name: node_pid(master, name) for name in REJOINING_NODES} == rejoining, "a rospy node was restarted"
    assert "turtlebot3_burger" in master.param("/robot_description")
    assert master.param("/mux/initial_topic") == "nav_vel"
    probe = master.probe  # a new probe, registered with the new master
    after = probe.wait_for_message("/odom", ODOMETRY, timeout=30)["pose"]["pose"]["position"]
    assert math.hypot(after["x"] - before["x"], after["y"] - before["y"]) < 0.02, "odometry jumped"
    probe.wait_for_message("/scan", SCAN, timeout=30)
    probe.wait_for_message("/tf_static", "tf2_msgs/TFMessage", start=0, timeout=30)  # latched
    assert probe.wait_for_message("/mux/selected", "std_msgs/String", start=0, timeout=30)["data"] == "nav_vel"
    source = KeySource(master)  # both directions again: a command reaches the wheels
    try:
        wait_until_driving(control)
    finally:
        source.kill()
    watch_until_at_rest(control)
    saved = master.param("/turtlebot3_core/saved_odometry")
    restart_roscore(master)  # again: the guards respawned after the first restart must see this one too
    for name in DAEMON_NODES:
        master.wait_for_node(name, timeout=60)
    source = KeySource(master)
    try:
        wait_until_driving(control)
    finally:
        source.kill()
    watch_until_at_rest(control)
    wait_until(lambda: master.param("/turtlebot3_core/saved_odometry") != saved, 10,
               "the driver no longer saves its odometry (for a respawn to resume from)")
    assert all(process.running() for process in launches), "a launch had to be restarted"

