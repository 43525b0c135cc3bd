"""Faults of the snap's daemons and of the mapping app's map saving, through the snap's own scripts and snapsim.

A daemon whose main process is SIGKILLed is stopped whole and restarted, per
its restart-condition; one stopped while its launch is still starting ends at
once. A large map saved within the stop timeout; the save SIGKILLed, or the
power lost, midway; the disk full: in every case
current_map.yaml names a complete map, the new one or the previous one, which
stays usable.
"""
import os
import signal
import socket
import subprocess
import time

import pytest
import yaml

from snapsim.supervisor import root_processes
from testkit.real_robot import node_pid
from testkit.ros_harness import descendants, kill_quietly, wait_until
from testkit.snap_system import (
    REPO,
    SNAPSIM,
    app_shell,
    dated_maps,
    emptied_map_folder,
    install_turtlebot3c,
    main_command_line,
    saved_map,
)
from turtlebot3c_maps.map_files import load_map

SIDE = 1000  # cells: 50 m x 50 m at 5 cm, far more than a TurtleBot maps in one session
LARGE_MAP = {"header": {"frame_id": "map"},
             "info": {"resolution": 0.05, "width": SIDE, "height": SIDE,
                      "origin": {"position": {"x": -25.0, "y": -25.0}}},
             "data": ([0] * (SIDE - 20) + [100] * 10 + [-1] * 10) * SIDE}


def stop_timeout():
    snapcraft = yaml.safe_load((REPO / "snap" / "snapcraft.yaml").read_text())
    return float(snapcraft["apps"]["mapping"]["stop-timeout"].rstrip("s"))


@pytest.fixture(scope="module")
def system(ros_master, tmp_path_factory):
    system = install_turtlebot3c(tmp_path_factory.mktemp("map-faults"), ros_master)
    ros_master.probe.publish("/map", "nav_msgs/OccupancyGrid", LARGE_MAP, latch=True)
    yield system
    system.shutdown()


@pytest.fixture
def maps(system, ros_master):
    """The services' map folder with one previous map, current."""
    folder = emptied_map_folder(system)
    saved_map(folder)
    app_shell(system, "mapping", "install_last_map.sh", ros_master.uri)
    return folder


def assert_previous_map_is_current_and_usable(maps, previous):
    assert os.readlink(maps / "current_map.yaml") == previous
    occupancy = load_map(maps / "current_map.yaml")
    assert occupancy.data.shape == (3, 4)
    assert dated_maps(maps) == [previous]


def test_stopping_mapping_with_a_large_map_saves_it_within_the_stop_timeout(system, maps):
    system.snapsim("start", "turtlebot3c.mapping")
    main_command_line(system, "mapping")
    started = time.monotonic()
    system.snapsim("stop", "turtlebot3c.mapping")
    took = time.monotonic() - started
    print(f"stop with a {SIDE} x {SIDE} map: saved and installed in {took:.1f} s (stop-timeout {stop_timeout():.0f} s)")
    current = os.readlink(maps / "current_map.yaml")
    occupancy = load_map(maps / current)
    assert occupancy.data.shape == (SIDE, SIDE)
    assert took < stop_timeout() / 2, "saving a large map takes more than half the stop timeout"


def test_a_stop_while_the_launch_asks_whether_the_master_runs_ends_it_at_once_without_a_traceback(ros_env):
    # roslaunch asks inside a bare `except:`, which swallowed the KeyboardInterrupt of a SIGINT (the
    # mapping daemon's stop signal): the launch went on to start nodes no stop reached, and the stop
    # waited out the stop-timeout.
    silent_master = socket.socket()  # takes the connection and never answers: roslaunch waits in its ask
    silent_master.bind(("127.0.0.1", 0))
    silent_master.listen()
    silent_master.settimeout(60)
    uri = f"http://127.0.0.1:{silent_master.getsockname()[1]}"
    joining = REPO / "snap" / "local" / "roslaunch_joining.py"
    launch = subprocess.Popen(
        [str(joining), "--wait", "turtlebot3c_slam", "turtlebot3c_mapping.launch"],
        env=dict(ros_env, ROS_MASTER_URI=uri), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        asking, _ = silent_master.accept()
        launch.send_signal(signal.SIGINT)
        output = launch.communicate(timeout=10)[0]
        asking.close()
    except subprocess.TimeoutExpired:
        launch.kill()
        raise AssertionError(f"the launch outlived its SIGINT:\n{launch.communicate()[0]}") from None
    finally:
        silent_master.close()
        if launch.poll() is None:  # it never asked (the accept timed out)
            launch.kill()
            launch.wait()
    assert launch.returncode == -signal.SIGINT, output
    assert "Traceback" not in output, output


def map_saver_running(system):
    """The map_saver node itself (a Python process), not rosrun's shell or its `find` on the way."""
    for pid in root_processes(system.root):
        try:
            words = open(f"/proc/{pid}/cmdline", "rb").read().split(b"\0")
        except OSError:
            continue
        if "python" in os.path.basename(words[0].decode()) and any(word.endswith(b"/map_saver") for word in words):
            return pid
    return None


def test_a_save_sigkilled_midway_keeps_the_previous_map_current_and_usable(system, maps):
    previous = os.readlink(maps / "current_map.yaml")
    system.snapsim("start", "turtlebot3c.mapping")
    main_command_line(system, "mapping")
    stopping = subprocess.Popen([str(SNAPSIM), "--root", str(system.root), "stop", "turtlebot3c.mapping"],
                                env=system.env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    saver = wait_until(lambda: map_saver_running(system), 60, "the stop-command never ran map_saver", interval=0.01)
    kill_quietly(saver, signal.SIGKILL)
    try:
        output = stopping.communicate(timeout=120)[0]
    except subprocess.TimeoutExpired:
        stopping.kill()
        raise AssertionError(f"snapsim stop hung:\n{system.logs('turtlebot3c.mapping')}") from None
    assert stopping.returncode == 0, output
    assert_previous_map_is_current_and_usable(maps, previous)
    assert not list(maps.glob("new_map*")), list(maps.iterdir())
    logs = system.logs("turtlebot3c.mapping")
    assert "save_map: the map could not be saved" in logs
    assert f"no new map was saved; the current map stays {previous}" in logs


def test_power_lost_while_saving_leaves_a_usable_current_map_and_the_next_save_cleans_up(system, ros_master, maps):
    previous = os.readlink(maps / "current_map.yaml")
    # The whole save, as the machine would run it; pulling the power = SIGKILL to all of it at once.
    saving = subprocess.Popen(
        [str(SNAPSIM), "--root", str(system.root), "run", "--shell", "turtlebot3c.mapping", "-c",
         "save_map.sh && install_last_map.sh"],
        env=dict(system.env, ROS_MASTER_URI=ros_master.uri, ROS_HOSTNAME="127.0.0.1"),
        start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wait_until(lambda: list(maps.glob(".saving.*")), 60, "the save never started", interval=0.01)
    time.sleep(0.2)  # somewhere in map_saver's work
    for pid in [saving.pid] + descendants(saving.pid):
        kill_quietly(pid, signal.SIGKILL)
    saving.wait(10)
    assert_previous_map_is_current_and_usable(maps, previous)
    done = app_shell(system, "mapping", "save_map.sh && install_last_map.sh", ros_master.uri)
    assert "is now the current map" in done.stdout
    assert not list(maps.glob(".saving.*")), "a killed save's leftovers stayed"
    assert load_map(maps / "current_map.yaml").data.shape == (SIDE, SIDE)


@pytest.fixture
def full_disk(maps):
    """The map folder on a 512 KiB tmpfs (with the previous map in it): too small for the large map."""
    saved = {path.name: (path.read_bytes() if not path.is_symlink() else os.readlink(path)) for path in maps.iterdir()}
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=512k", "turtlebot3c-test-full", str(maps)], check=True)
    try:
        for name, content in saved.items():
            if isinstance(content, str):
                os.symlink(content, maps / name)
            else:
                (maps / name).write_bytes(content)
        yield maps
    finally:
        subprocess.run(["umount", str(maps)], check=True)


def test_a_full_disk_during_saving_is_a_clear_error_and_the_previous_map_stays(system, ros_master, full_disk):
    maps = full_disk
    previous = os.readlink(maps / "current_map.yaml")
    done = app_shell(system, "mapping", "save_map.sh; install_last_map.sh", ros_master.uri, check=False)
    assert "No space left on device" in done.stderr, done.stderr
    assert "save_map: the map could not be saved" in done.stderr
    assert f"no new map was saved; the current map stays {previous}" in done.stderr
    assert_previous_map_is_current_and_usable(maps, previous)
    assert not list(maps.glob(".saving.*")) and not list(maps.glob("new_map*"))


@pytest.mark.parametrize("app, node", [("core", "/robot_state_publisher"), ("teleop", "/mux")])
def test_a_sigkilled_daemon_is_restarted_by_the_snaps_restart_policy(system, ros_master, app, node):
    before = system.wait_state("turtlebot3c", app, ["active"])["main_pid"]
    main_command_line(system, app)
    ros_master.wait_for_node(node, timeout=60)
    node_before = node_pid(ros_master, node)
    kill_quietly(before, signal.SIGKILL)
    wait_until(lambda: system.status("turtlebot3c", app)["main_pid"] not in (None, before), 60,
               lambda: f"{app} was not restarted: {system.status('turtlebot3c', app)}\n{system.logs('turtlebot3c')}")
    system.wait_state("turtlebot3c", app, ["active"])
    wait_until(lambda: node_pid(ros_master, node) not in (None, node_before), 60, f"{node} did not come back")
    assert before not in root_processes(system.root)
    assert not os.path.exists(f"/proc/{node_before}") or b"Z" in open(f"/proc/{node_before}/stat", "rb").read()
