"""The motion watchdog after the mux: commands pass, silence becomes one zero command."""
import signal
import time

import pytest

from testkit.ros_harness import wait_until
from turtlebot3c_teleop.velocity_watchdog import VelocityWatchdog

TWIST = "geometry_msgs/Twist"
ODOMETRY = "nav_msgs/Odometry"
TIMEOUT = 0.3  # the launch file's watchdog_timeout


def test_no_stop_before_any_command():
    assert not VelocityWatchdog(0.5).should_stop(now=100.0)


def test_stop_once_after_timeout_then_quiet_until_next_command():
    watchdog = VelocityWatchdog(0.5)
    watchdog.command_received(now=10.0)
    assert not watchdog.should_stop(now=10.49)
    assert watchdog.should_stop(now=10.5)
    assert not watchdog.should_stop(now=11.0)
    watchdog.command_received(now=12.0)
    assert watchdog.should_stop(now=12.6)


def test_non_positive_timeout_is_rejected():
    with pytest.raises(ValueError, match="positive"):
        VelocityWatchdog(0.0)


@pytest.fixture(scope="module")
def teleop(ros_master):
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.wait_for_service("/mux/select")
    ros_master.wait_for_node("/velocity_watchdog")
    return ros_master


def test_selected_source_reaches_cmd_vel_and_silence_sends_zero(teleop):
    probe = teleop.probe
    probe.call("/mux/select", {"topic": "key_vel"})
    probe.subscribe("/cmd_vel", TWIST)
    start = probe.count("/cmd_vel")
    for _ in range(5):
        probe.publish("/key_vel", TWIST, {"linear": {"x": 0.1}})
        time.sleep(0.1)
    last_sent = time.time()
    probe.wait_for_message("/cmd_vel", TWIST, where=lambda m: m["linear"]["x"] == 0.1, start=start)
    zero = probe.wait_for_message(
        "/cmd_vel", TWIST, timeout=5, start=start,
        where=lambda m: m["linear"]["x"] == 0.0 and m["angular"]["z"] == 0.0)
    assert zero is not None
    stop_time = next(entry["t"] for entry in probe.timed_messages("/cmd_vel", start)
                     if entry["msg"]["linear"]["x"] == 0.0)
    assert TIMEOUT - 0.1 <= stop_time - last_sent <= TIMEOUT + 0.3


def test_unselected_source_does_not_reach_cmd_vel(teleop):
    probe = teleop.probe
    probe.call("/mux/select", {"topic": "key_vel"})
    probe.subscribe("/cmd_vel", TWIST)
    start = probe.count("/cmd_vel")
    for _ in range(5):
        probe.publish("/joy_vel", TWIST, {"linear": {"x": 0.2}})
        time.sleep(0.05)
    time.sleep(0.5)
    assert [m for m in probe.messages("/cmd_vel", start) if m["linear"]["x"] == 0.2] == []


def last_moving_and_first_stop(probe, start):
    """Times (probe clock) of the last moving command and of the first zero after it on /cmd_vel."""
    entries = probe.timed_messages("/cmd_vel", start)
    last_moving = max(i for i, entry in enumerate(entries) if entry["msg"]["linear"]["x"] != 0.0)
    stop = next(entry for entry in entries[last_moving + 1:] if entry["msg"]["linear"]["x"] == 0.0)
    return entries[last_moving]["t"], stop["t"]


@pytest.fixture(scope="module")
def simulated_robot(teleop):
    teleop.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=empty", "noise:=none", "model:=burger")
    teleop.wait_for_publisher("/sim/ground_truth", timeout=60)
    return teleop


def test_simulated_robot_stops_within_half_a_second_when_its_source_is_sigkilled(simulated_robot):
    probe = simulated_robot.probe
    probe.call("/mux/select", {"topic": "key_vel"})
    probe.subscribe("/cmd_vel", TWIST)
    probe.subscribe("/sim/ground_truth", ODOMETRY)
    start = probe.count("/cmd_vel")
    source = simulated_robot.start(["rostopic", "pub", "-r", "10", "/key_vel", TWIST, "{linear: {x: 0.15}}"],
                                   name="key_vel_source")
    probe.wait_for_message("/sim/ground_truth", ODOMETRY, timeout=30,
                           where=lambda m: m["twist"]["twist"]["linear"]["x"] == pytest.approx(0.15))
    truth_start = probe.count("/sim/ground_truth")
    source.signal(signal.SIGKILL)
    killed_at = time.time()
    source.wait(10)
    stopped = probe.wait_for_message("/sim/ground_truth", ODOMETRY, start=truth_start, timeout=5,
                                     where=lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
    wait_until(lambda: probe.count("/sim/ground_truth") >= truth_start + 60, 20, "ground truth stopped coming")

    truth = probe.timed_messages("/sim/ground_truth", truth_start)
    stop_index = next(i for i, entry in enumerate(truth) if entry["msg"] == stopped)
    robot_stopped_at = truth[stop_index]["t"]
    x_at_stop = stopped["pose"]["pose"]["position"]["x"]
    assert all(entry["msg"]["pose"]["pose"]["position"]["x"] == x_at_stop for entry in truth[stop_index:]), \
        "the robot moved again after it stopped"
    last_command, zero_sent = last_moving_and_first_stop(probe, start)
    silence = zero_sent - last_command
    assert TIMEOUT - 0.05 <= silence <= TIMEOUT + 0.3, f"the zero came {silence:.3f} s after the last command"
    print(f"SIGKILL -> zero on /cmd_vel {zero_sent - killed_at:.3f} s, "
          f"-> simulated robot at rest {robot_stopped_at - killed_at:.3f} s")
    assert robot_stopped_at - killed_at <= 0.5 + 0.3


def test_switching_to_a_silent_input_stops_the_robot(teleop):
    probe = teleop.probe
    probe.call("/mux/select", {"topic": "key_vel"})
    probe.subscribe("/cmd_vel", TWIST)
    start = probe.count("/cmd_vel")
    probe.publish("/key_vel", TWIST, {"linear": {"x": 0.12}})
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == 0.12)
    probe.call("/mux/select", {"topic": "__none"})
    probe.wait_for_message("/cmd_vel", TWIST, start=start, timeout=5, where=lambda m: m["linear"]["x"] == 0.0)
    last_command, stopped = last_moving_and_first_stop(probe, start)
    assert TIMEOUT - 0.05 <= stopped - last_command <= TIMEOUT + 0.3


def test_mux_starts_on_nav_vel(make_master):
    master = make_master()
    master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    master.wait_for_service("/mux/select")
    probe = master.probe
    assert probe.wait_for_message("/mux/selected", "std_msgs/String", start=0)["data"].lstrip("/") == "nav_vel"
    probe.subscribe("/cmd_vel", TWIST)

    def nav_vel_reached_cmd_vel():
        # The mux advertises its output on its first input message, so early ones may find no subscriber yet.
        probe.publish("/nav_vel", TWIST, {"linear": {"x": 0.05}})
        return any(m["linear"]["x"] == 0.05 for m in probe.messages("/cmd_vel"))
    wait_until(nav_vel_reached_cmd_vel, 20, "a command on nav_vel never reached /cmd_vel", interval=0.1)
    probe.publish("/key_vel", TWIST, {"linear": {"x": 0.07}})
    probe.wait_for_message("/cmd_vel", TWIST, start=0, where=lambda m: m["linear"]["x"] == 0.0)
    assert [m for m in probe.messages("/cmd_vel") if m["linear"]["x"] == 0.07] == []
