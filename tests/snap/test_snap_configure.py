"""The snap's options: defaults, validation by the configure hook (under dash), restarts, ROS network."""
import os
import signal

import pytest

from testkit.ros_harness import descendants, wait_until
from testkit.snap_system import install_turtlebot3c, main_command_line, pid_alive, user_environment

HOSTNAME = os.uname().nodename
DEFAULTS = {"simulation": False, "turtlebot3-model": "waffle_pi", "lds-model": "LDS-01",
            "ros-master-host": f"{HOSTNAME}.local", "opencr-port": "/dev/ttyACM0", "lds-port": "/dev/ttyUSB0",
            "map": "latest"}


@pytest.fixture(scope="module")
def system(ros_master, tmp_path_factory):
    system = install_turtlebot3c(tmp_path_factory.mktemp("snap-configure"), ros_master)
    yield system
    system.shutdown()


@pytest.fixture
def restore_defaults(system):
    yield
    current = system.config("turtlebot3c")
    changed = [f"{key}={value}" for key, value in DEFAULTS.items() if current.get(key) != value]
    if changed:
        system.snapsim("set", "turtlebot3c", *[item.replace("False", "false") for item in changed])


def main_pid(system, app):
    return system.wait_state("turtlebot3c", app, ["active"])["main_pid"]


def test_install_sets_every_default(system):
    assert system.config("turtlebot3c") == DEFAULTS


def test_core_is_launched_with_the_configured_robot(system):
    assert main_command_line(system, "core")[-7:] == [
        "turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=false", "model:=waffle_pi",
        "lds_model:=LDS-01", "opencr_port:=/dev/ttyACM0", "lds_port:=/dev/ttyUSB0"]


@pytest.mark.parametrize("key, value, stored", [
    ("simulation", "true", True), ("simulation", "false", False), ("simulation", "1", True),
    ("simulation", "0", False), ("turtlebot3-model", "burger", "burger"), ("turtlebot3-model", "waffle", "waffle"),
    ("turtlebot3-model", "waffle_pi", "waffle_pi"), ("lds-model", "LDS-02", "LDS-02"),
    ("lds-model", "LDS-01", "LDS-01"), ("ros-master-host", "localhost", "localhost"),
    ("ros-master-host", "192.168.1.20", "192.168.1.20"), ("ros-master-host", "my-robot.local", "my-robot.local"),
    ("opencr-port", "/dev/serial/by-id/usb-ROBOTIS_OpenCR-if00", "/dev/serial/by-id/usb-ROBOTIS_OpenCR-if00"),
    ("lds-port", "/dev/ttyUSB1", "/dev/ttyUSB1"),
])
def test_valid_value_is_accepted(system, restore_defaults, key, value, stored):
    system.snapsim("set", "turtlebot3c", f"{key}={value}")
    assert system.config("turtlebot3c")[key] == stored


@pytest.mark.parametrize("key, value, allowed", [
    ("simulation", "yes", "allowed values: true, false"),
    ("simulation", "2", "allowed values: true, false"),
    ("turtlebot3-model", "waffle-pi", "allowed values: burger, waffle, waffle_pi"),
    ("turtlebot3-model", "Burger", "allowed values: burger, waffle, waffle_pi"),
    ("lds-model", "LDS-03", "allowed values: LDS-01, LDS-02"),
    ("lds-model", "lds-01", "allowed values: LDS-01, LDS-02"),
    ("ros-master-host", "robot local", "use a host name"),
    ("ros-master-host", "-robot", "use a host name"),
    ("ros-master-host", "robot..local", "use a host name"),
    ("ros-master-host", "http://robot:11311", "use a host name"),
    ("ros-master-host", "a" * 64 + ".local", "use a host name"),
    ("opencr-port", "ttyACM0", "use a device path under /dev"),
    ("opencr-port", "/dev/../etc/passwd", "use a device path under /dev"),
    ("lds-port", "/tmp/ttyUSB0", "use a device path under /dev"),
])
def test_invalid_value_is_rejected_naming_allowed_values_and_changes_nothing(system, key, value, allowed):
    before = system.config("turtlebot3c")
    done = system.snapsim("set", "turtlebot3c", f"{key}={value}", check=False)
    assert done.returncode == 1
    assert f"{key}: '{value}' is not allowed" in done.stderr and allowed in done.stderr
    assert system.config("turtlebot3c") == before


@pytest.mark.parametrize("key", ["simulation", "turtlebot3-model", "lds-model", "ros-master-host", "opencr-port"])
def test_unsetting_an_option_is_rejected(system, key):
    before = system.config("turtlebot3c")
    done = system.snapsim("unset", "turtlebot3c", key, check=False)
    assert done.returncode == 1 and f"{key}: '' is not allowed" in done.stderr
    assert system.config("turtlebot3c") == before


@pytest.mark.parametrize("payload", ["$(touch {marker})", "`touch {marker}`", "x;touch {marker}",
                                     "x\ntouch {marker}", "$(touch${{IFS}}{marker})"])
def test_injection_through_an_option_executes_nothing(system, tmp_path, payload):
    marker = tmp_path / "pwned"
    for key in ("ros-master-host", "turtlebot3-model", "opencr-port"):
        done = system.snapsim("set", "turtlebot3c", f"{key}={payload.format(marker=marker)}", check=False)
        assert done.returncode == 1
    assert not marker.exists()
    assert system.config("turtlebot3c") == DEFAULTS


def test_model_change_restarts_core_but_not_teleop(system, restore_defaults):
    core, teleop = main_pid(system, "core"), main_pid(system, "teleop")
    system.snapsim("set", "turtlebot3c", "turtlebot3-model=burger")
    assert main_pid(system, "core") != core
    assert main_pid(system, "teleop") == teleop
    assert "model:=burger" in main_command_line(system, "core")


def test_setting_the_same_values_restarts_nothing(system):
    core, teleop = main_pid(system, "core"), main_pid(system, "teleop")
    system.snapsim("set", "turtlebot3c", "turtlebot3-model=waffle_pi", "lds-model=LDS-01")
    assert (main_pid(system, "core"), main_pid(system, "teleop")) == (core, teleop)


def test_master_host_change_restarts_core_and_teleop(system, restore_defaults, ros_master):
    core, teleop = main_pid(system, "core"), main_pid(system, "teleop")
    system.snapsim("set", "turtlebot3c", "ros-master-host=localhost")
    assert main_pid(system, "core") != core and main_pid(system, "teleop") != teleop
    ros_master.wait_for_service("/mux/select", timeout=60)


def test_option_change_does_not_start_a_stopped_core(system, restore_defaults):
    system.snapsim("stop", "turtlebot3c.core")
    try:
        system.snapsim("set", "turtlebot3c", "lds-model=LDS-02")
        assert system.status("turtlebot3c", "core")["state"] == "inactive"
    finally:
        system.snapsim("start", "turtlebot3c.core")
    assert "lds_model:=LDS-02" in main_command_line(system, "core")


def shell(system, app, script, *args, **env):
    done = system.snapsim("run", "--shell", f"turtlebot3c.{app}", "-c", script, "_", *args,
                          env=dict(user_environment(**env), TURTLEBOT3C_BUILD_DIR=system.env["TURTLEBOT3C_BUILD_DIR"]))
    return done.stdout.strip().splitlines()[-1]


def test_ros_network_points_at_the_configured_master_when_none_is_given(system):
    line = shell(system, "teleop", 'echo "$ROS_MASTER_URI $ROS_HOSTNAME"')
    assert line == f"http://{HOSTNAME}.local:11311 {HOSTNAME}.local"


def test_ros_network_uses_our_own_name_when_the_master_is_another_machine(system, restore_defaults):
    system.snapsim("set", "turtlebot3c", "ros-master-host=robot.example")
    line = shell(system, "teleop", 'echo "$ROS_MASTER_URI $ROS_HOSTNAME"')
    assert line == f"http://robot.example:11311 {HOSTNAME}.local"


def test_ros_network_keeps_a_master_uri_given_on_purpose(system):
    line = shell(system, "teleop", 'echo "$ROS_MASTER_URI"', ROS_MASTER_URI="http://10.0.0.9:11311")
    assert line == "http://10.0.0.9:11311"


def test_arguments_pass_the_whole_chain_intact(system, ros_master):
    script = 'printf "<%s>" "$@"'
    args = ("two words", "*", "", "$HOME")
    expected = "<two words><*><><$HOME>"
    assert shell(system, "teleop", script, *args) == expected
    assert shell(system, "key", script, *args, ROS_MASTER_URI=ros_master.uri, ROS_HOSTNAME="127.0.0.1") == expected


def test_library_path_has_no_empty_entry_that_would_mean_the_current_folder(system):
    entries = shell(system, "teleop", 'echo "$LD_LIBRARY_PATH"').split(":")
    assert "" not in entries
    assert any(entry.endswith("/blas") for entry in entries)  # snap-level, with the arch triplet filled in


def test_teleop_killed_by_sigkill_restarts_and_its_orphaned_nodes_go_too(system, ros_master):
    roslaunch = main_pid(system, "teleop")
    nodes = wait_until(lambda: descendants(roslaunch), 30, "teleop's roslaunch started no node")
    os.kill(roslaunch, signal.SIGKILL)  # roslaunch's nodes live in sessions of their own
    wait_until(lambda: system.status("turtlebot3c", "teleop")["main_pid"] not in (None, roslaunch), 60,
               "teleop was not restarted")
    wait_until(lambda: not any(pid_alive(pid) for pid in nodes), 30, "the killed roslaunch's nodes survived")
    assert system.status("turtlebot3c", "teleop")["restarts"] >= 1
    ros_master.wait_for_service("/mux/select", timeout=60)
