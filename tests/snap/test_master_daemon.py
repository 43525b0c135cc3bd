"""The roscore app: the one master, which the other daemons wait for and no `snap set` takes away.

Core stopped and started no longer disturbs teleop, mapping or navigation: their nodes keep
their registrations (same processes, same URIs, same topics) and /map keeps its contents.
Mapping and navigation started right after install and `snap set` work the first time, and
/map flows on SLAM's cadence while mapping runs. When the master is another machine's, the
roscore app runs none and says so, and the daemons wait for it, naming its URI, for a bounded
time. A port another program holds is waited for, with one line saying so. A fresh install
links root's $SNAP_USER_COMMON/map (the upstream snap's folder) to the maps.
"""
import os
import socket
import time

import pytest

from testkit import ros_harness
from testkit.ros_harness import free_port, wait_until
from testkit.snap_system import (
    DAEMON_NODES,
    REPO,
    SnapSystem,
    close_probe,
    install_with_own_master,
    node_uri,
    rosmaster_pids,
    wait_for_working_robot,
)

GRID = "nav_msgs/OccupancyGrid"
MAP_UPDATE_INTERVAL = 2.0  # s, the mapping launch's map_update_interval


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    system, master = install_with_own_master(tmp_path_factory.mktemp("master_daemon"))
    try:
        system.snapsim("set", "turtlebot3c", "simulation=true", "turtlebot3-model=burger")
        master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "model:=burger", "noise:=none")
        yield system, master
    finally:
        master.shutdown()
        system.shutdown()


def graph_of(master, apps):
    """Each node of `apps`: its URI and pid, and the topics and services it is registered on."""
    publishers, subscribers, services = master.system_state()
    nodes = [name for app in apps for name in DAEMON_NODES[app]] + ["/teleop_master_guard"]

    def entries(table, node):
        return sorted(name for name, names in table if node in names)
    return {node: (node_uri(master, node), entries(publishers, node), entries(subscribers, node),
                   entries(services, node)) for node in nodes}


def settled_graph(master, apps, ready_topic):
    """graph_of once the nodes have made their registrations (`ready_topic` published, no change for 2 s)."""
    master.wait_for_publisher(ready_topic, timeout=120)
    last = [None]

    def unchanged():
        graph, last[0] = last[0], graph_of(master, apps)
        return graph == last[0] and graph
    time.sleep(1.0)
    return wait_until(unchanged, 60, "the graph kept changing", interval=2.0)


def stop_and_start_core(system, master):
    system.snapsim("stop", "turtlebot3c.core")
    wait_until(lambda: node_uri(master, "/robot_state_publisher") is None, 30, "robot_state_publisher stayed")
    system.snapsim("start", "turtlebot3c.core")
    wait_for_working_robot(system, master, 60, apps=["core"])


def same_cells(before, after):
    assert after["info"]["width"] == before["info"]["width"]
    assert after["info"]["height"] == before["info"]["height"]
    for axis in ("x", "y"):
        assert after["info"]["origin"]["position"][axis] == pytest.approx(before["info"]["origin"]["position"][axis])
    known = [index for index, cell in enumerate(before["data"]) if cell != -1]
    assert known, "the map had nothing in it"
    kept = sum(1 for index in known if after["data"][index] == before["data"][index])
    return kept / len(known)


def test_mapping_and_navigation_work_first_time_and_a_restarted_core_disturbs_neither(robot):
    system, master = robot
    # Right after install and snap set: mapping works the first time, with no wait by hand.
    system.snapsim("start", "turtlebot3c.mapping")
    wait_for_working_robot(system, master, 90, apps=["teleop", "mapping"])
    first = master.probe.wait_for_message("/map", GRID, timeout=60, start=0)
    # /map flows on its cadence though nothing changes (the robot stands still)
    mark = master.probe.count("/map")
    wait_until(lambda: master.probe.count("/map") >= mark + 3, 10 * MAP_UPDATE_INTERVAL, "/map stopped flowing")
    stamps = [entry["msg"]["header"]["stamp"] for entry in master.probe.timed_messages("/map", mark)]
    seconds = stamps  # to_plain gives a time as float seconds
    gaps = [later - earlier for earlier, later in zip(seconds, seconds[1:])]
    assert all(gap >= MAP_UPDATE_INTERVAL - 0.1 for gap in gaps), gaps

    graph = settled_graph(master, ["teleop", "mapping"], "/map")
    assert all(uri for uri, *_ in graph.values()), graph
    before = master.probe.messages("/map")[-1]
    stop_and_start_core(system, master)
    assert graph_of(master, ["teleop", "mapping"]) == graph
    mark = master.probe.count("/map")
    after = master.probe.wait_for_message("/map", GRID, timeout=30, start=mark)
    assert same_cells(before, after) >= 0.99
    assert same_cells(first, after) >= 0.99
    assert system.status("turtlebot3c", "mapping")["starts"] == 1
    assert system.status("turtlebot3c", "teleop")["starts"] == 1

    # The map is saved and current; navigation on it works the first time, and core's restart
    # leaves it alone too.
    system.snapsim("stop", "turtlebot3c.mapping")
    system.snapsim("start", "turtlebot3c.navigation")
    wait_for_working_robot(system, master, 120, apps=["teleop", "navigation"])
    assert system.status("turtlebot3c", "navigation")["starts"] == 1
    graph = settled_graph(master, ["teleop", "navigation"], "/move_base/status")
    assert all(uri for uri, *_ in graph.values()), graph
    close_probe(master)  # a new subscriber: map_server's latched map, SLAM being gone
    served = master.probe.wait_for_message("/map", GRID, timeout=30, start=0)
    assert same_cells(after, served) >= 0.99  # the map SLAM had is the one saved and served
    stop_and_start_core(system, master)
    assert graph_of(master, ["teleop", "navigation"]) == graph
    close_probe(master)
    again = master.probe.wait_for_message("/map", GRID, timeout=30, start=0)
    assert again["data"] == served["data"] and again["info"] == served["info"]
    assert len(rosmaster_pids(system)) == 1
    system.snapsim("stop", "turtlebot3c.navigation")


def test_the_master_is_started_once_by_the_roscore_app_and_the_others_wait_for_it(robot):
    system, master = robot
    logs = system.logs("turtlebot3c")
    assert f"roscore: the ROS master runs at {master.uri}" in logs
    assert "Address already in use" not in logs
    for app in ("core", "teleop"):
        words = system.logs(f"turtlebot3c.{app}")
        assert "wait_for_master: " in words or f"ROS_MASTER_URI={master.uri}" in words


def test_a_fresh_install_links_roots_map_folder_to_the_maps_folder(robot):
    system, _ = robot
    link = system.root / "root" / "snap" / "turtlebot3c" / "common" / "map"
    assert link.is_symlink()
    assert link.resolve() == (system.root / "var" / "snap" / "turtlebot3c" / "common" / "maps").resolve()


def test_with_the_master_on_another_machine_no_master_runs_here_and_the_daemons_wait_for_it_boundedly(tmp_path):
    remote_uri = f"http://192.0.2.1:{free_port()}"  # TEST-NET-1: never this machine, never answers
    system = SnapSystem(tmp_path / "root", build_dir=ros_harness.BUILD, etc_environment={
        "ROS_MASTER_URI": remote_uri, "ROS_HOSTNAME": "127.0.0.1", "ROS_MASTER_WAIT": "3"})
    try:
        system.snapsim("install", REPO, "--dangerous")
        wait_until(lambda: "no ROS master answers" in system.logs("turtlebot3c.core"), 60,
                   lambda: system.logs("turtlebot3c"))
        logs = system.logs("turtlebot3c")
        assert f"roscore: the ROS master is on another machine ({remote_uri}" in logs, logs
        assert "no master runs here" in logs
        assert f"wait_for_master: waiting up to 3 s for the ROS master at {remote_uri}" in logs
        failure = next(line for line in logs.splitlines() if "no ROS master answers" in line)
        assert remote_uri in failure and "ros-master-host" in failure and "Traceback" not in logs
        assert rosmaster_pids(system) == []
        assert os.path.exists(system.root / "var/snap/turtlebot3c/common/maps")
    finally:
        system.shutdown()


def test_a_port_held_by_another_program_is_waited_for_with_one_line_and_no_traceback(tmp_path):
    holder = socket.socket()
    holder.bind(("127.0.0.1", free_port()))
    holder.listen()
    port = holder.getsockname()[1]
    uri = f"http://127.0.0.1:{port}"
    system = SnapSystem(tmp_path / "root", build_dir=ros_harness.BUILD, etc_environment={
        "ROS_MASTER_URI": uri, "ROS_HOSTNAME": "127.0.0.1"})
    try:
        system.snapsim("install", REPO, "--dangerous")
        taken = f"roscore: port {port} of this machine is taken by a program that is not a ROS master"
        wait_until(lambda: taken in system.logs("turtlebot3c.roscore"), 60, lambda: system.logs("turtlebot3c"))
        time.sleep(12)  # two more looks at the port
        logs = system.logs("turtlebot3c.roscore")
        assert logs.count(taken) == 1, logs
        assert rosmaster_pids(system) == [] and "Traceback" not in logs and "Address already in use" not in logs
        holder.close()
        wait_until(lambda: f"roscore: the ROS master runs at {uri}" in system.logs("turtlebot3c.roscore"), 30,
                   lambda: system.logs("turtlebot3c"))
        wait_until(lambda: len(rosmaster_pids(system)) == 1, 30, lambda: system.logs("turtlebot3c"))
    finally:
        holder.close()
        system.shutdown()
