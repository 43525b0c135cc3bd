"""The joystick node: js_event structs from a fake /dev/input/js device become sensor_msgs/Joy."""

import pytest

from testkit.fake_joystick import FULL, FakeJoystick
from testkit.ros_harness import wait_until
from turtlebot3c_common.backoff import Backoff
from turtlebot3c_teleop.joystick_device import (
    JS_EVENT_AXIS,
    JS_EVENT_BUTTON,
    JS_EVENT_INIT,
    JoystickState,
    JsEvent,
    encode_event,
    parse_events,
    scale_axis,
)

JOY = "sensor_msgs/Joy"


# --- the js_event format and the state it builds ------------------------------------------


def test_events_are_8_byte_structs_and_a_partial_one_waits_for_the_rest():
    first = JsEvent(123456, -32767, JS_EVENT_AXIS, 1)
    second = JsEvent(123460, 1, JS_EVENT_BUTTON | JS_EVENT_INIT, 4)
    data = encode_event(first) + encode_event(second)
    assert len(data) == 16
    assert data[:8] == (123456).to_bytes(4, "little") + (-32767).to_bytes(2, "little", signed=True) + bytes([2, 1])
    events, rest = parse_events(data[:11])
    assert events == [first] and rest == data[8:11]
    events, rest = parse_events(rest + data[11:])
    assert events == [second] and rest == b""
    assert second.is_init and second.kind == JS_EVENT_BUTTON


def test_axes_are_inverted_with_the_dead_zone_cut_out():
    assert scale_axis(-FULL, 0.05) == 1.0  # stick pushed up
    assert scale_axis(FULL, 0.05) == -1.0
    assert scale_axis(-32768, 0.05) == 1.0
    assert scale_axis(1000, 0.05) == 0.0  # inside the dead zone
    assert scale_axis(-16384, 0.0) == pytest.approx(0.5, abs=1e-4)
    halfway_past_dead_zone = int(FULL * 0.05 + (FULL - FULL * 0.05) / 2)
    assert scale_axis(halfway_past_dead_zone, 0.05) == pytest.approx(-0.5, abs=1e-4)
    with pytest.raises(ValueError, match="deadzone"):
        scale_axis(0, 1.0)


def test_state_grows_to_the_highest_number_seen_and_reports_changes():
    state = JoystickState(deadzone=0.0)
    assert state.apply(JsEvent(0, 1, JS_EVENT_BUTTON | JS_EVENT_INIT, 3))
    assert state.buttons == [0, 0, 0, 1]
    assert state.apply(JsEvent(0, -FULL, JS_EVENT_AXIS, 1))
    assert state.axes == [0.0, 1.0]
    assert not state.apply(JsEvent(1, -FULL, JS_EVENT_AXIS, 1))
    assert state.released() == ([0.0, 0.0], [0, 0, 0, 0])


def test_reopen_delays_double_up_to_a_ceiling_and_reset():
    backoff = Backoff(0.25, 2.0)
    assert [backoff.next_delay() for _ in range(6)] == [0.25, 0.5, 1.0, 2.0, 2.0, 2.0]
    backoff.reset()
    assert backoff.next_delay() == 0.25


# --- the node against a fake device ---------------------------------------------------------


@pytest.fixture(scope="module")
def joystick(ros_master, tmp_path_factory):
    """The joystick node, started before its device exists (as when the pad is plugged in later)."""
    device = FakeJoystick(tmp_path_factory.mktemp("dev") / "js0")
    node = ros_master.rosrun("turtlebot3c_teleop", "joy_node", f"_dev:={device.path}", "_autorepeat_rate:=10.0")
    ros_master.wait_for_node("/joystick")
    ros_master.probe.subscribe("/joy", JOY)
    yield device, node
    device.close()


def wait_for_joy(probe, start, where, timeout=15):
    return probe.wait_for_message("/joy", JOY, timeout=timeout, start=start, where=where)


def test_missing_device_is_reported_and_then_picked_up(ros_master, joystick):
    device, node = joystick
    wait_until(lambda: "cannot open" in node.log_text(), 20, lambda: f"no clear message:\n{node.log_text()}")
    assert "is the joystick plugged in?" in node.log_text()
    start = ros_master.probe.count("/joy")
    device.plug(axes=(0, 0, FULL, 0, 0, 0), buttons=(0,) * 11)
    joy = wait_for_joy(ros_master.probe, start, lambda m: len(m["axes"]) == 6)
    assert joy["axes"] == [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
    assert joy["buttons"] == [0] * 11
    assert f"joystick {device.path}: opened" in node.log_text()


def plugged_in(probe, device):
    if not device.plugged():
        start = probe.count("/joy")
        device.plug()
        wait_for_joy(probe, start, lambda m: len(m["axes"]) == 6)
    return device


def test_stick_and_buttons_are_published_and_the_state_repeats_at_10_hz(ros_master, joystick):
    probe = ros_master.probe
    device = plugged_in(probe, joystick[0])
    start = probe.count("/joy")
    device.axis(1, -FULL)
    device.button(4, True)
    joy = wait_for_joy(probe, start, lambda m: m["axes"][1] == 1.0 and m["buttons"][4] == 1)
    assert joy["axes"][0] == 0.0
    seen = probe.count("/joy")
    wait_until(lambda: probe.count("/joy") >= seen + 5, 10, "the state was not repeated while nothing changed")
    assert all(m["axes"][1] == 1.0 and m["buttons"][4] == 1 for m in probe.messages("/joy", seen))
    device.axis(1, 0)
    device.button(4, False)
    wait_for_joy(probe, start, lambda m: m["axes"][1] == 0.0 and m["buttons"][4] == 0)


def test_unplug_reports_everything_released_and_replug_resumes(ros_master, joystick):
    probe = ros_master.probe
    device, node = plugged_in(probe, joystick[0]), joystick[1]
    start = probe.count("/joy")
    device.button(4, True)
    device.axis(0, FULL)
    wait_for_joy(probe, start, lambda m: m["buttons"][4] == 1 and m["axes"][0] == -1.0)
    lost_start = probe.count("/joy")
    device.unplug()
    released = wait_for_joy(probe, lost_start, lambda m: not any(m["buttons"]) and not any(m["axes"]))
    assert len(released["axes"]) == 6 and len(released["buttons"]) == 11
    wait_until(lambda: f"joystick {device.path}: lost" in node.log_text(), 10,
               lambda: f"no clear message about the lost joystick:\n{node.log_text()}")
    opened_before = node.log_text().count(": opened")
    replug_start = probe.count("/joy")
    device.plug(axes=(0, 0, 0, -FULL, 0, 0, 0, 0), buttons=(0,) * 11)
    joy = wait_for_joy(probe, replug_start, lambda m: len(m["axes"]) == 8)
    assert joy["axes"][3] == 1.0
    assert node.log_text().count(": opened") == opened_before + 1
    assert node.running()


def test_a_press_and_release_read_together_are_both_published(ros_master, joystick):
    probe = ros_master.probe
    device = plugged_in(probe, joystick[0])
    start = probe.count("/joy")
    device.write([device.event(JS_EVENT_BUTTON, 1, 2), device.event(JS_EVENT_BUTTON, 0, 2)])
    pressed = wait_for_joy(probe, start, lambda m: m["buttons"][2] == 1)
    assert pressed["buttons"] == [0, 0, 1] + [0] * 8
    messages = probe.messages("/joy", start)
    index = next(i for i, m in enumerate(messages) if m["buttons"][2] == 1)
    wait_for_joy(probe, start + index + 1, lambda m: m["buttons"][2] == 0)


@pytest.mark.parametrize("parameter, expected", [
    ("_deadzone:=1.5", "deadzone must be in [0, 1), got 1.5"),
    ("_autorepeat_rate:=often", "parameter ~autorepeat_rate must be a finite number, got 'often'"),
])
def test_a_parameter_the_node_cannot_run_with_stops_it_with_one_line(ros_master, parameter, expected):
    status, log = ros_master.rosrun_refused("turtlebot3c_teleop", "joy_node", parameter)
    assert status != 0
    assert expected in log and "Traceback" not in log
