"""The motion watchdog after the mux: commands pass, silence becomes one zero command."""
import signal
import time

import pytest

from ros_harness import wait_until
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


def last_moving_and_first_stop(probe, start):
    """Times (probe clock) of the last moving command and of the first zero after it on /cmd_vel."""
    entries = probe.timed_messages("/cmd_vel", start)
    last_moving = max(i for i, entry in enumerate(entries) if entry["msg"]["linear"]["x"] != 0.0)
    stop = next(entry for entry in entries[last_moving + 1:] if entry["msg"]["linear"]["x"] == 0.0)
    return entries[last_moving]["t"], stop["t"]


def test_sigkilled_source_is_stopped_within_half_a_second(teleop):
    # The simulator node (turtlebot3c_sim) did not exist when this was written: the
    # test asserts on /cmd_vel, the topic the driver and the simulator both obey.
    probe = teleop.probe
    probe.call("/mux/select", {"topic": "key_vel"})
    probe.subscribe("/cmd_vel", TWIST)
    start = probe.count("/cmd_vel")
    source = teleop.start(["rostopic", "pub", "-r", "10", "/key_vel", TWIST, "{linear: {x: 0.15}}"],
                          name="key_vel_source")
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == 0.15)
    source.signal(signal.SIGKILL)
    killed_at = time.time()
    source.wait(10)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, timeout=5, where=lambda m: m["linear"]["x"] == 0.0)
    last_command, stopped = last_moving_and_first_stop(probe, start)
    assert stopped > killed_at
    silence = stopped - last_command
    assert 0.45 <= silence <= 0.5 + 0.3, f"zero came {silence:.3f} s after the last command"
    print(f"stop latency after SIGKILL: {stopped - killed_at:.3f} s")


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
    assert 0.45 <= stopped - last_command <= 0.8


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
