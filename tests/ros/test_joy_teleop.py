"""Joystick to velocity: deadman, per-model scaling and mux buttons, alone and against the real mux."""
import pytest

from testkit.fake_joystick import FULL, FakeJoystick
from testkit.ros_harness import wait_until
from testkit.roscore_restart import restart_roscore
from turtlebot3c_description.models import get_model
from turtlebot3c_teleop.joy_teleop import DEFAULT_CONFIG, MUX_NONE, ConfigError, JoyTeleop, config_from_params

TWIST = "geometry_msgs/Twist"
JOY = "sensor_msgs/Joy"
DEADMAN = DEFAULT_CONFIG.deadman_button


def buttons_with(*pressed, count=11):
    return [1 if index in pressed else 0 for index in range(count)]


def stick(forward=0.0, left=0.0):
    return [left, forward, 0.0, 0.0, 0.0, 0.0]


# --- the mapping alone --------------------------------------------------------------------


def test_no_motion_without_the_deadman_button():
    teleop = JoyTeleop(DEFAULT_CONFIG, get_model("burger"))
    assert teleop.update(stick(forward=1.0), buttons_with()).velocity is None


def test_held_deadman_scales_the_stick_to_the_models_maximum():
    for name in ("burger", "waffle"):
        model = get_model(name)
        teleop = JoyTeleop(DEFAULT_CONFIG, model)
        linear, angular = teleop.update(stick(forward=1.0, left=-0.5), buttons_with(DEADMAN)).velocity
        assert linear == pytest.approx(model.max_linear_velocity)
        assert angular == pytest.approx(-0.5 * model.max_angular_velocity)


def test_releasing_the_deadman_gives_one_zero_then_nothing():
    teleop = JoyTeleop(DEFAULT_CONFIG, get_model("burger"))
    teleop.update(stick(forward=1.0), buttons_with(DEADMAN))
    assert teleop.update(stick(forward=1.0), buttons_with()).velocity == (0.0, 0.0)
    assert teleop.update(stick(forward=1.0), buttons_with()).velocity is None


def test_mux_buttons_select_on_the_press_not_while_held():
    teleop = JoyTeleop(DEFAULT_CONFIG, get_model("burger"))
    assert teleop.update(stick(), buttons_with(1)).select == ["key_vel"]
    assert teleop.update(stick(), buttons_with(1)).select == []
    assert teleop.update(stick(), buttons_with()).select == []
    assert teleop.update(stick(), buttons_with(0, 3)).select == ["joy_vel", MUX_NONE]
    assert teleop.update(stick(), buttons_with(2)).select == ["nav_vel"]


def test_a_joystick_without_the_configured_inputs_is_named_and_does_not_drive():
    teleop = JoyTeleop(DEFAULT_CONFIG, get_model("burger"))
    assert teleop.missing_inputs([0.5], [0, 0]) == ["axis 1", "button 4", "button 2", "button 3"]
    assert teleop.update([0.5], [0, 0]).velocity is None


def test_config_from_yaml_like_params_and_clear_errors():
    config = config_from_params({"linear": {"axis": 4, "scale": 0.5}, "deadman_button": 5,
                                 "mux_buttons": [{"button": 0, "topic": "joy_vel"}]})
    assert config.linear.axis == 4 and config.linear.scale == 0.5
    assert config.angular == DEFAULT_CONFIG.angular
    assert config.mux_buttons == {0: "joy_vel"}
    with pytest.raises(ConfigError, match="scale must be a number in"):
        config_from_params({"linear": {"axis": 1, "scale": 2.0}})
    with pytest.raises(ConfigError, match="unknown joy_teleop parameters"):
        config_from_params({"linera": {"axis": 1}})
    with pytest.raises(ConfigError, match="both the deadman and a mux button"):
        config_from_params({"deadman_button": 0})
    with pytest.raises(ConfigError, match="non-negative integer"):
        config_from_params({"mux_buttons": [{"button": -1, "topic": "joy_vel"}]})


# --- joy.launch with a fake joystick, against the real mux ---------------------------------


@pytest.fixture(scope="module")
def joy_app(ros_master, tmp_path_factory):
    device = FakeJoystick(tmp_path_factory.mktemp("dev") / "js0")
    device.plug()
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.launch("turtlebot3c_teleop", "joy.launch", "model:=burger", f"dev:={device.path}")
    for node in ("/mux", "/velocity_watchdog", "/joystick", "/joy_teleop"):
        ros_master.wait_for_node(node)
    probe = ros_master.probe
    for topic, type_ in (("/joy", JOY), ("/joy_vel", TWIST), ("/cmd_vel", TWIST), ("/mux/selected", "std_msgs/String")):
        probe.subscribe(topic, type_)
    ros_master.wait_for_publisher("/joy")
    yield device
    device.close()


def press(probe, device, button, expected_selection):
    """Press and release `button`; the mux must then announce `expected_selection`."""
    start = probe.count("/mux/selected")
    device.button(button, True)
    device.button(button, False)
    probe.wait_for_message("/mux/selected", "std_msgs/String", start=start, timeout=15,
                           where=lambda m: m["data"] == expected_selection)


def joy_messages_pass(probe, count=3):
    """Let `count` more joystick messages go by, so joy_teleop has seen what came before."""
    seen = probe.count("/joy")
    wait_until(lambda: probe.count("/joy") >= seen + count, 10, "the joystick stopped publishing")


def test_buttons_select_each_mux_input(ros_master, joy_app):
    probe = ros_master.probe
    press(probe, joy_app, 1, "key_vel")
    press(probe, joy_app, 2, "nav_vel")
    press(probe, joy_app, 3, MUX_NONE)
    press(probe, joy_app, 0, "joy_vel")


def test_stick_without_deadman_moves_nothing(ros_master, joy_app):
    probe = ros_master.probe
    press(probe, joy_app, 0, "joy_vel")
    start = probe.count("/joy_vel")
    joy_app.axis(1, -FULL)
    probe.wait_for_message("/joy", JOY, where=lambda m: m["axes"][1:2] == [1.0])
    joy_messages_pass(probe)
    assert probe.messages("/joy_vel", start) == []
    joy_app.axis(1, 0)


def test_deadman_drives_through_the_mux_and_release_sends_one_zero(ros_master, joy_app):
    probe = ros_master.probe
    burger = get_model("burger")
    press(probe, joy_app, 0, "joy_vel")
    start = probe.count("/cmd_vel")
    joy_start = probe.count("/joy_vel")
    joy_app.axis(1, -FULL)
    joy_app.button(DEADMAN, True)
    moving = probe.wait_for_message(
        "/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == pytest.approx(burger.max_linear_velocity))
    assert moving["angular"]["z"] == 0.0
    joy_messages_pass(probe)
    release_start = probe.count("/joy_vel")
    joy_app.button(DEADMAN, False)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == 0.0)
    joy_messages_pass(probe)
    after_release = probe.messages("/joy_vel", release_start)
    assert [(m["linear"]["x"], m["angular"]["z"]) for m in after_release][-1:] == [(0.0, 0.0)]
    assert sum(1 for m in after_release if m["linear"]["x"] == 0.0) == 1
    assert len(probe.messages("/joy_vel", joy_start)) > len(after_release)
    joy_app.axis(1, 0)


def test_selecting_key_vel_cuts_the_joystick_off_from_the_robot(ros_master, joy_app):
    probe = ros_master.probe
    press(probe, joy_app, 1, "key_vel")
    start = probe.count("/cmd_vel")
    joy_start = probe.count("/joy_vel")
    joy_app.axis(1, -FULL)
    joy_app.button(DEADMAN, True)
    probe.wait_for_message("/joy_vel", TWIST, start=joy_start, where=lambda m: m["linear"]["x"] > 0)
    joy_messages_pass(probe)
    assert [m for m in probe.messages("/cmd_vel", start) if m["linear"]["x"] > 0] == []
    joy_app.button(DEADMAN, False)
    joy_app.axis(1, 0)


def test_unplugging_the_joystick_while_driving_stops_the_robot(ros_master, joy_app):
    probe = ros_master.probe
    press(probe, joy_app, 0, "joy_vel")
    start = probe.count("/cmd_vel")
    joy_app.axis(1, -FULL)
    joy_app.button(DEADMAN, True)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] > 0)
    joy_start = probe.count("/joy_vel")
    joy_app.unplug()
    # The zero comes from joy_teleop (the joystick reported everything released), not the watchdog.
    probe.wait_for_message("/joy_vel", TWIST, start=joy_start, where=lambda m: m["linear"]["x"] == 0.0)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == 0.0)
    joy_app.plug()


def test_after_a_roscore_restart_a_button_selects_the_joystick_again_and_it_drives(ros_master, joy_app):
    """Last here: the joystick app registers again in process, so it needs no restart; the mux,
    restarted by its guard, is back on nav_vel, so the joystick drives only once selected anew."""
    restart_roscore(ros_master)
    for node in ("/mux", "/velocity_watchdog", "/joystick", "/joy_teleop"):
        ros_master.wait_for_node(node, timeout=60)
    probe = ros_master.probe
    for topic, type_ in (("/joy", JOY), ("/cmd_vel", TWIST), ("/mux/selected", "std_msgs/String")):
        probe.subscribe(topic, type_)
    assert probe.wait_for_message("/mux/selected", "std_msgs/String", start=0, timeout=30)["data"] == "nav_vel"
    press(probe, joy_app, 0, "joy_vel")
    start = probe.count("/cmd_vel")
    joy_app.axis(1, -FULL)
    joy_app.button(DEADMAN, True)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] > 0)
    joy_app.button(DEADMAN, False)
    probe.wait_for_message("/cmd_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] == 0.0)
    joy_app.axis(1, 0)
