"""The motion watchdog after the mux: commands pass, silence becomes one zero command."""
import time

import pytest

from turtlebot3c_teleop.velocity_watchdog import VelocityWatchdog

TWIST = "geometry_msgs/Twist"


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
    assert 0.4 <= stop_time - last_sent <= 0.8


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
