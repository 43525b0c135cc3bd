"""Keyboard teleoperation: the key map and ramp, and the key app driven through a real pseudo-terminal."""
import os
import signal
import termios
import xmlrpc.client

import pytest

from testkit.pty_session import PtySession
from testkit.ros_harness import wait_until
from testkit.roscore_restart import restart_roscore
from turtlebot3c_description.models import get_model
from turtlebot3c_teleop.keyboard_teleop import (
    KeyboardTeleop,
    help_text,
    is_quit_key,
    is_stop_key,
    limits_for_model,
    split_keys,
)
from turtlebot3c_teleop.terminal import key_mode, key_mode_attributes

TWIST = "geometry_msgs/Twist"
NODE = "/turtlebot3_teleop_keyboard"
SELECTED = "std_msgs/String"

# --- the key map, limits and ramp -------------------------------------------------------


def teleop_for(model_name):
    return KeyboardTeleop(limits_for_model(get_model(model_name)))


def test_limits_and_steps_follow_the_model_not_burgers_table():
    burger = limits_for_model(get_model("burger"))
    waffle = limits_for_model(get_model("waffle_pi"))
    assert burger.max_linear == pytest.approx(get_model("burger").max_linear_velocity)
    assert waffle.max_linear == pytest.approx(get_model("waffle_pi").max_linear_velocity)
    assert waffle.max_linear > burger.max_linear
    assert waffle.max_angular < burger.max_angular
    assert waffle.linear_step != burger.linear_step
    assert waffle.angular_step != burger.angular_step


def test_w_x_a_d_move_the_targets_by_one_step_each():
    teleop = teleop_for("burger")
    step = teleop.limits
    for key in "www":
        assert teleop.press(key)
    teleop.press("x")
    teleop.press("a")
    assert teleop.target_linear == pytest.approx(2 * step.linear_step)
    assert teleop.target_angular == pytest.approx(step.angular_step)
    teleop.press("d")
    teleop.press("d")
    assert teleop.target_angular == pytest.approx(-step.angular_step)


def test_w_then_x_returns_exactly_to_zero():
    teleop = teleop_for("waffle")
    for key in "wwwwwwwxxxxxxx":
        teleop.press(key)
    assert teleop.target_linear == 0.0


def test_targets_are_clamped_to_the_models_limits():
    teleop = teleop_for("waffle")
    for _ in range(100):
        teleop.press("w")
        teleop.press("d")
    assert teleop.target_linear == pytest.approx(teleop.limits.max_linear)
    assert teleop.target_angular == pytest.approx(-teleop.limits.max_angular)
    teleop.press("x")
    assert teleop.target_linear < teleop.limits.max_linear


def test_output_ramps_toward_the_target_half_a_step_per_tenth_of_a_second():
    teleop = teleop_for("burger")
    for _ in range(4):
        teleop.press("w")
    teleop.advance(0.1)
    assert teleop.linear == pytest.approx(teleop.limits.linear_step / 2)
    for _ in range(7):
        teleop.advance(0.1)
    assert teleop.linear == pytest.approx(4 * teleop.limits.linear_step)
    teleop.advance(0.1)
    assert teleop.linear == pytest.approx(4 * teleop.limits.linear_step)


def test_space_and_s_stop_at_once_without_ramp():
    for stop_key in (" ", "s"):
        teleop = teleop_for("burger")
        for _ in range(5):
            teleop.press("w")
            teleop.press("a")
            teleop.advance(1.0)
        assert teleop.linear > 0 and teleop.angular > 0
        assert is_stop_key(stop_key)
        teleop.press(stop_key)
        assert (teleop.linear, teleop.angular, teleop.target_linear, teleop.target_angular) == (0, 0, 0, 0)


def test_other_keys_change_nothing_and_ctrl_c_quits():
    teleop = teleop_for("burger")
    assert not teleop.press("q")
    assert not teleop.press("\x1b")
    assert (teleop.target_linear, teleop.target_angular) == (0, 0)
    assert is_quit_key("\x03")
    assert not is_quit_key("w")


def test_arrow_and_function_keys_are_not_read_as_letters():
    assert split_keys("w\x1b[Ax\x1b[D\x1bOPa\x1b[15~d") == ["w", "x", "a", "d"]
    assert split_keys("\x1b") == []
    assert split_keys("\x03") == ["\x03"]


def test_status_line_and_help_name_the_model_and_its_limits():
    teleop = teleop_for("waffle_pi")
    teleop.press("w")
    teleop.advance(1.0)
    line = teleop.status_line()
    assert line.startswith("waffle_pi: linear +0.013 m/s (target +0.013, max 0.266)")
    assert "angular +0.00 rad/s (target +0.00, max 1.85)" in line
    text = help_text(teleop.limits, "/key_vel")
    assert "waffle_pi" in text and "/key_vel" in text and "max 0.266 m/s" in text


def test_non_positive_step_is_rejected():
    with pytest.raises(ValueError, match="linear_step must be positive"):
        limits_for_model(get_model("burger"), linear_step=0.0)


def test_key_mode_turns_off_line_buffering_echo_and_signal_keys():
    master, slave = os.openpty()
    try:
        mode = key_mode_attributes(termios.tcgetattr(slave))
        for flag in (termios.ICANON, termios.ECHO, termios.ISIG):
            assert not mode[3] & flag
        assert mode[6][termios.VMIN] == 1
    finally:
        os.close(master)
        os.close(slave)


def test_key_mode_gives_the_terminal_back_when_an_exception_escapes():
    master, slave = os.openpty()
    try:
        before = termios.tcgetattr(slave)
        with pytest.raises(RuntimeError, match="boom"), key_mode(slave):
            assert termios.tcgetattr(slave)[3] & termios.ICANON == 0
            raise RuntimeError("boom")
        assert termios.tcgetattr(slave) == before
    finally:
        os.close(master)
        os.close(slave)


# --- the key app through a pseudo-terminal ---------------------------------------------


@pytest.fixture
def pty_session(ros_master):
    sessions = []

    def start(*args):
        session = PtySession(ros_master.env, args)
        sessions.append(session)
        return session
    yield start
    for session in sessions:
        session.close()


def start_key_app(ros_master, pty_session, model="waffle"):
    session = pty_session("roslaunch", "turtlebot3c_teleop", "key.launch", f"model:={model}")
    wait_until(session.in_key_mode, 30, lambda: f"the key node never put the terminal in key mode:\n{session.text()}")
    ros_master.probe.wait_for_message("/key_vel", TWIST, timeout=20)
    return session


def node_pid(ros_master, name):
    code, _, uri = ros_master.master_api().lookupNode("/test", name)
    assert code == 1, f"node {name} not registered"
    return xmlrpc.client.ServerProxy(uri).getPid("/test")[2]


def wait_for_key_vel(probe, start, linear, angular):
    def matches(message):
        return (message["linear"]["x"] == pytest.approx(linear, abs=1e-9)
                and message["angular"]["z"] == pytest.approx(angular, abs=1e-9))
    return probe.wait_for_message("/key_vel", TWIST, timeout=15, start=start, where=matches)


def assert_stopped_cleanly(ros_master, session, start, reason):
    session.wait_exit()
    assert session.attributes() == session.original, "terminal attributes were not restored"
    messages = ros_master.probe.messages("/key_vel", start)
    assert messages, "nothing was published on /key_vel"
    assert messages[-1]["linear"]["x"] == 0.0 and messages[-1]["angular"]["z"] == 0.0
    assert f"stopped ({reason}); zero velocity sent" in session.text()


def test_keys_drive_key_vel_within_the_models_limits(ros_master, pty_session):
    probe = ros_master.probe
    probe.subscribe("/key_vel", TWIST)
    session = start_key_app(ros_master, pty_session, model="waffle")
    limits = limits_for_model(get_model("waffle"))
    start = probe.count("/key_vel")
    session.type("www")
    wait_for_key_vel(probe, start, 3 * limits.linear_step, 0.0)
    session.type("\x1b[D\x1b[Ca")  # left and right arrows send ESC [ D and ESC [ C: not d, not a
    wait_for_key_vel(probe, start, 3 * limits.linear_step, limits.angular_step)
    session.type(" ")
    wait_for_key_vel(probe, start, 0.0, 0.0)
    session.type("w" * 100)
    wait_for_key_vel(probe, start, limits.max_linear, 0.0)
    assert max(m["linear"]["x"] for m in probe.messages("/key_vel", start)) == pytest.approx(limits.max_linear)
    assert "waffle: linear" in session.text() and "max 0.266" in session.text()
    session.type("\x03")
    assert_stopped_cleanly(ros_master, session, start, "Ctrl-C")


@pytest.mark.parametrize("signum", [signal.SIGHUP, signal.SIGTERM])
def test_signal_restores_terminal_and_sends_zero(ros_master, pty_session, signum):
    probe = ros_master.probe
    probe.subscribe("/key_vel", TWIST)
    session = start_key_app(ros_master, pty_session)
    start = probe.count("/key_vel")
    session.type("wwd")
    probe.wait_for_message("/key_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] > 0)
    os.kill(node_pid(ros_master, NODE), signum)
    assert_stopped_cleanly(ros_master, session, start, signal.Signals(signum).name)


def test_closing_the_terminal_sends_zero_and_ends_the_app(ros_master, pty_session):
    probe = ros_master.probe
    probe.subscribe("/key_vel", TWIST)
    session = start_key_app(ros_master, pty_session)
    start = probe.count("/key_vel")
    session.type("ww")
    probe.wait_for_message("/key_vel", TWIST, start=start, where=lambda m: m["linear"]["x"] > 0)
    session.hang_up()
    session.wait_exit()
    wait_until(lambda: NODE not in ros_master.node_names(), 20, "the key node outlived its terminal")
    last = probe.messages("/key_vel", start)[-1]
    assert last["linear"]["x"] == 0.0 and last["angular"]["z"] == 0.0


def test_without_a_terminal_it_says_so_and_fails(ros_master):
    process = ros_master.rosrun("turtlebot3c_teleop", "teleop_key")
    assert process.wait(30) != 0
    assert "standard input is not a terminal" in process.log_text()
    assert NODE not in ros_master.node_names()


def test_unknown_model_is_refused_with_the_known_ones_and_terminal_untouched(ros_master, pty_session):
    session = pty_session("rosrun", "turtlebot3c_teleop", "teleop_key", "_model:=tank")
    assert session.wait_exit() == 2
    assert "unknown TurtleBot3 model 'tank'; known models: burger, waffle, waffle_pi" in session.text()
    assert session.attributes() == session.original


@pytest.mark.parametrize("parameter, expected", [
    ("_rate:=.inf", "parameter ~rate must be a finite number, got inf"),
    ("_linear_step:=.nan", "parameter ~linear_step must be a finite number, got nan"),
])
def test_a_parameter_it_cannot_run_with_is_refused_in_one_line_and_terminal_untouched(ros_master, pty_session,
                                                                                     parameter, expected):
    # A node name of its own: a private parameter outlives its node, and would reach the next key app.
    own_name = "__name:=key_refusing" + parameter[:parameter.index(":=")]
    session = pty_session("rosrun", "turtlebot3c_teleop", "teleop_key", own_name, "_model:=burger", parameter)
    assert session.wait_exit() == 2
    assert expected in session.text() and "Traceback" not in session.text()
    assert session.attributes() == session.original


def test_after_a_roscore_restart_the_next_key_selects_key_vel_again_and_drives(ros_master, pty_session):
    """Last here (it restarts the module's master): the key app registers again in process; the mux,
    restarted by its guard, is back on nav_vel until a key is pressed."""
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.wait_for_service("/mux/select", timeout=60)
    session = start_key_app(ros_master, pty_session, model="waffle")
    ros_master.probe.call("/mux/select", {"topic": "key_vel"})  # as the snap's command chain does
    session.type("wwwww")  # driving when the master goes
    restart_roscore(ros_master)
    for node in ("/mux", "/velocity_watchdog", NODE):
        ros_master.wait_for_node(node, timeout=60)
    probe = ros_master.probe
    probe.subscribe("/cmd_vel", TWIST)
    assert probe.wait_for_message("/mux/selected", SELECTED, start=0, timeout=30)["data"] == "nav_vel"
    wait_until(lambda: "stopped; the next key selects key_vel again" in session.text(), 20,
               lambda: f"the app never said the mux must be selected again:\n{session.text()}")
    start = probe.count("/cmd_vel")
    session.type("w")
    probe.wait_for_message("/mux/selected", SELECTED, start=0, where=lambda m: m["data"] == "key_vel", timeout=30)
    one_step = limits_for_model(get_model("waffle")).linear_step
    probe.wait_for_message("/cmd_vel", TWIST, start=start, timeout=30,
                           where=lambda m: m["linear"]["x"] == pytest.approx(one_step, abs=1e-9))
    reached = probe.count("/cmd_vel")
    wait_until(lambda: probe.count("/cmd_vel") >= reached + 5, 10, "/cmd_vel stopped")  # the ramp would go on
    assert max(m["linear"]["x"] for m in probe.messages("/cmd_vel", start)) <= one_step + 1e-9, \
        "the keys drove on from the speed before the restart"
    session.type("\x03")
    session.wait_exit()
    assert session.attributes() == session.original, "terminal attributes were not restored"
    assert "stopped (Ctrl-C); zero velocity sent" in session.text()
