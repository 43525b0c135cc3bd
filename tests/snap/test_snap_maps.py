"""Mapping, navigation and the mux through the snap's own scripts, daemons and command-chains."""
import os

import pytest

from snapsim.supervisor import root_processes
from testkit import ros_harness
from testkit.ros_harness import wait_until
from testkit.snap_system import (
    app_shell,
    dated_maps,
    emptied_map_folder,
    install_turtlebot3c,
    main_command_line,
    mux_mark,
    saved_map,
    selected_mux_input,
)

MAP = {"header": {"frame_id": "map"},
       "info": {"resolution": 0.05, "width": 4, "height": 3, "origin": {"position": {"x": -1.0, "y": -2.0}}},
       "data": [0, 0, 100, -1] * 3}


# A service that takes calls and never answers (argv: name, type). `timeout` alone does not end a
# `rosservice call` waiting on one: it outlives SIGTERM and SIGINT.
SILENT_SERVICE = """
import sys, time, rospy, roslib.message
rospy.init_node("silent_service", anonymous=True)
rospy.Service(sys.argv[1], roslib.message.get_service_class(sys.argv[2]), lambda request: time.sleep(3600))
rospy.spin()
"""


def silent_service(master, name, service_type):
    master.start([ros_harness.python(), "-c", SILENT_SERVICE, name, service_type], name="silent_service")
    master.wait_for_service(name, timeout=60)


@pytest.fixture(scope="module")
def system(ros_master, tmp_path_factory):
    system = install_turtlebot3c(tmp_path_factory.mktemp("snap-maps"), ros_master)
    yield system
    system.shutdown()


@pytest.fixture
def maps(system):
    """The services' map folder, emptied for the test."""
    return emptied_map_folder(system)


def test_key_and_joy_select_their_mux_input_through_their_chain(system, ros_master):
    mark = mux_mark(ros_master)
    app_shell(system, "joy", "true", ros_master.uri)
    assert selected_mux_input(ros_master, "joy_vel", since=mark) == "joy_vel"
    mark = mux_mark(ros_master)
    app_shell(system, "key", "true", ros_master.uri)
    assert selected_mux_input(ros_master, "key_vel", since=mark) == "key_vel"


def test_mux_selection_fails_clearly_when_teleop_is_not_running(system, ros_master):
    system.snapsim("stop", "turtlebot3c.teleop")
    try:
        done = app_shell(system, "key", "echo RAN", ros_master.uri, check=False, MUX_SELECT_TIMEOUT=2)
    finally:
        system.snapsim("start", "turtlebot3c.teleop")
        ros_master.wait_for_service("/mux/select", timeout=60)
    assert done.returncode == 1 and "RAN" not in done.stdout
    assert "could not select 'key_vel': /mux/select did not answer within 2 s" in done.stderr
    assert "sudo snap start turtlebot3c.teleop" in done.stderr


def test_mux_selection_that_is_never_answered_fails_clearly_after_its_deadline(system, make_master):
    master = make_master()
    silent_service(master, "/mux/select", "topic_tools/MuxSelect")  # a hung mux
    done = app_shell(system, "key", "echo RAN", master.uri, check=False, MUX_SELECT_TIMEOUT=2)
    assert done.returncode == 1 and "RAN" not in done.stdout
    assert "could not select 'key_vel': /mux/select did not answer within 2 s" in done.stderr


def test_mapping_stop_saves_a_dated_map_and_makes_it_current(system, ros_master, maps):
    ros_master.probe.publish("/map", "nav_msgs/OccupancyGrid", MAP, latch=True)
    app_shell(system, "joy", "true", ros_master.uri)
    mark = mux_mark(ros_master)
    system.snapsim("start", "turtlebot3c.mapping")
    assert "model:=waffle_pi" in main_command_line(system, "mapping")
    assert selected_mux_input(ros_master, "key_vel", since=mark) == "key_vel"
    system.snapsim("stop", "turtlebot3c.mapping")
    [dated] = dated_maps(maps)
    stem = dated[:-len(".yaml")]
    assert os.readlink(maps / "current_map.yaml") == dated
    assert f"image: {stem}.pgm" in (maps / dated).read_text().splitlines()
    assert (maps / f"{stem}.pgm").read_bytes().startswith(b"P5")
    # the mapping launch may record the session (new_map.bag): it is kept under the map's name
    left = sorted(path.name for path in maps.iterdir() if path.name != ".lock")  # the folder's lock
    assert left in (sorted([dated, f"{stem}.pgm", "current_map.yaml"]),
                    sorted([dated, f"{stem}.pgm", f"{stem}.bag", "current_map.yaml"])), left
    logs = system.logs("turtlebot3c.mapping")
    assert "save_map: map saved" in logs and f"install_last_map: {maps}/{dated} is now the current map" in logs
    # No SLAM node here (the probe published the map): saved as it was, in one line that says why.
    assert "save_map: the map is saved unrefined: SLAM's refine_map gave no refined map within 150 s: " \
        "ERROR: Service [/refine_map] is not available." in logs


def test_mapping_stop_saves_the_map_even_when_teleop_is_down(system, ros_master, maps):
    ros_master.probe.publish("/map", "nav_msgs/OccupancyGrid", MAP, latch=True)
    system.snapsim("start", "turtlebot3c.mapping")
    main_command_line(system, "mapping")
    system.snapsim("stop", "turtlebot3c.teleop")
    try:
        system.snapsim("stop", "turtlebot3c.mapping")
    finally:
        system.snapsim("start", "turtlebot3c.teleop")
        ros_master.wait_for_service("/mux/select", timeout=60)
    assert len(dated_maps(maps)) == 1 and (maps / "current_map.yaml").exists()


def test_stop_with_no_new_map_keeps_previous_current_map(system, make_master, maps):
    saved_map(maps)
    quiet = make_master()  # a master where nobody publishes /map
    app_shell(system, "mapping", "install_last_map.sh", quiet.uri)
    previous = os.readlink(maps / "current_map.yaml")
    done = app_shell(system, "mapping", "save_map.sh; install_last_map.sh", quiet.uri, check=False)
    assert os.readlink(maps / "current_map.yaml") == previous
    assert dated_maps(maps) == [previous]
    assert "save_map: the map could not be saved" in done.stderr
    assert f"no new map was saved; the current map stays {previous}" in done.stderr
    assert not list(maps.glob(".saving*")) and not list(maps.glob("new_map*"))


def test_a_refinement_that_does_not_answer_in_time_leaves_the_map_saved_unrefined(system, make_master, maps):
    master = make_master()
    master.probe.publish("/map", "nav_msgs/OccupancyGrid", MAP, latch=True)
    silent_service(master, "/refine_map", "std_srvs/Trigger")  # a refinement longer than the stop allows
    done = app_shell(system, "mapping", "SAVE_REFINE_TIMEOUT=2 save_map.sh && install_last_map.sh", master.uri)
    assert "save_map: the map is saved unrefined: SLAM's refine_map gave no refined map within 2 s" in done.stderr
    [dated] = dated_maps(maps)
    assert os.readlink(maps / "current_map.yaml") == dated


def test_maps_saved_within_one_second_get_distinct_names_and_all_are_kept(system, ros_master, maps, tmp_path):
    # A `date` stuck on one second makes the three saves collide for sure.
    stuck_clock = tmp_path / "bin" / "date"
    stuck_clock.parent.mkdir()
    stuck_clock.write_text("#!/bin/sh\necho 2026-01-02_03-04-05\n")
    stuck_clock.chmod(0o755)
    script = ('PATH="$2:$PATH"; for n in 1 2 3; do'
              ' cp "$1/new.pgm" "$1/new_map.pgm"; cp "$1/new.yaml" "$1/new_map.yaml"; install_last_map.sh; done')
    saved_map(maps, "new")
    app_shell(system, "mapping", script, ros_master.uri, maps, stuck_clock.parent)
    stem = "2026-01-02_03-04-05"
    assert dated_maps(maps) == sorted([f"{stem}.yaml", f"{stem}_2.yaml", f"{stem}_3.yaml", "new.yaml"])
    assert os.readlink(maps / "current_map.yaml") == f"{stem}_3.yaml"
    for name in (stem, f"{stem}_2", f"{stem}_3"):
        assert (maps / f"{name}.yaml").read_text().splitlines()[0] == f"image: {name}.pgm"
        assert (maps / f"{name}.pgm").exists()
    assert [path.name for path in maps.glob(".*")] == [".lock"]  # no temporary left, only the folder's lock


def test_session_recording_keeps_the_name_of_its_map_or_is_kept_alone(system, ros_master, maps):
    saved_map(maps)
    (maps / "new_map.bag").write_bytes(b"#ROSBAG V2.0\n")
    app_shell(system, "mapping", "install_last_map.sh", ros_master.uri)
    stem = os.readlink(maps / "current_map.yaml")[:-len(".yaml")]
    assert (maps / f"{stem}.bag").read_bytes() == b"#ROSBAG V2.0\n"
    (maps / "new_map.bag.active").write_bytes(b"#ROSBAG V2.0\n")
    done = app_shell(system, "mapping", "install_last_map.sh", ros_master.uri)
    assert "no new map was saved" in done.stderr and "rosbag reindex" in done.stderr
    assert os.readlink(maps / "current_map.yaml") == f"{stem}.yaml"
    assert len(list(maps.glob("*.bag.active"))) == 1 and not list(maps.glob("new_map*"))


def test_navigation_without_a_map_refuses_clearly_and_is_not_restarted(system, ros_master, maps):
    mark = mux_mark(ros_master)
    system.snapsim("start", "turtlebot3c.navigation")
    status = system.wait_state("turtlebot3c", "navigation", ["inactive", "failed"])
    assert status["state"] == "inactive" and status["starts"] == 1 and status["restarts"] == 0
    assert "navigation: no map to navigate on" in system.logs("turtlebot3c.navigation")
    assert selected_mux_input(ros_master, "nav_vel", since=mark) == "nav_vel"
    assert selected_mux_input(ros_master, "key_vel", since=mark + 1) == "key_vel"  # handed back by post-stop


def test_navigation_drives_through_nav_vel_and_hands_back_key_vel_when_stopped(system, ros_master, maps):
    saved_map(maps)
    app_shell(system, "mapping", "install_last_map.sh", ros_master.uri)
    mark = mux_mark(ros_master)
    system.snapsim("start", "turtlebot3c.navigation")
    words = main_command_line(system, "navigation")
    assert f"map_file:={maps}/current_map.yaml" in words and "model:=waffle_pi" in words
    assert selected_mux_input(ros_master, "nav_vel", since=mark) == "nav_vel"
    mark = mux_mark(ros_master)
    system.snapsim("stop", "turtlebot3c.navigation")
    assert selected_mux_input(ros_master, "key_vel", since=mark) == "key_vel"
    wait_until(lambda: system.status("turtlebot3c", "navigation")["state"] == "inactive", 10, "navigation still up")


def test_remove_purge_leaves_nothing_of_the_snap_and_no_process(system, maps):
    saved_map(maps)
    system.snapsim("run", "--shell", "turtlebot3c.mapping", "-c", "install_last_map.sh")
    system.snapsim("remove", "--purge", "turtlebot3c")
    assert [path for path in system.root.rglob("*") if "turtlebot3c" in path.name] == []
    assert root_processes(system.root) == []
