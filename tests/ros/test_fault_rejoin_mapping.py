"""A roscore killed and restarted while mapping: SLAM registers again in process and keeps its map.

The simulator, the robot model (bringup simulation:=true) and the mapping launch run; the
robot drives, the roscore is SIGKILLed and a new one started on the same port. The same SLAM
process must be found by new subscribers with the map it had, take scans and odometry again
(the map grows as the robot drives on), and the stop's save must still get the map; the
session bag must hold the scans from both sides of the restart, and what publishers started
since the restart sent (the mapping guard registered `rosbag record` with the new master).
"""
import os
import subprocess
import time

import numpy as np
import pytest
from rosbags.rosbag1 import Reader

from testkit.real_robot import drive, node_pid
from testkit.ros_harness import REPO, wait_until
from testkit.roscore_restart import restart_roscore
from turtlebot3c_maps.map_files import UNKNOWN_PIXEL, read_pnm

GRID = "nav_msgs/OccupancyGrid"
SLAM = "/turtlebot3_slam_gmapping"
MAPPING_NODES = (SLAM, "/simulator", "/robot_state_publisher")


def known_cells(grid):
    """The centres of the map's known cells in world coordinates, in whole millimetres."""
    info = grid["info"]
    data = np.asarray(grid["data"]).reshape(info["height"], info["width"])
    rows, columns = np.nonzero(data != -1)
    origin = info["origin"]["position"]
    resolution = info["resolution"]
    return set(zip(np.round((origin["x"] + (columns + 0.5) * resolution) * 1000).astype(int),
                   np.round((origin["y"] + (rows + 0.5) * resolution) * 1000).astype(int)))


@pytest.fixture(scope="module")
def mapping(ros_master, tmp_path_factory):
    """Mapping a while, then the roscore restarted; what SLAM had just before the restart."""
    folder = tmp_path_factory.mktemp("rejoin-mapping")
    ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=turtlebot3_world", "model:=burger")
    ros_master.launch("turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=true", "model:=burger")
    launch = ros_master.launch("turtlebot3c_slam", "turtlebot3c_mapping.launch", "model:=burger",
                               f"bag:={folder / 'session.bag'}")
    for node in MAPPING_NODES + ("/mapping_recorder",):
        ros_master.wait_for_node(node, timeout=90)
    probe = ros_master.probe
    probe.wait_for_message("/map", GRID, timeout=90, start=0)
    drive(probe, 0.0, 1.0, 3.0)
    drive(probe, 0.0, 0.0, 0.5)
    turned = time.time()
    before = probe.wait_for_message("/map", GRID, timeout=30, start=0,  # one drawn during the turn or since
                                    where=lambda grid: grid["header"]["stamp"] > turned - 3.5)
    pid = node_pid(ros_master, SLAM)
    restarted = time.time()
    restart_roscore(ros_master)
    return {"master": ros_master, "launch": launch, "folder": folder, "before": before, "pid": pid,
            "restarted": restarted}


def test_slam_is_found_again_by_new_subscribers_with_the_map_it_had(mapping):
    master = mapping["master"]
    for node in MAPPING_NODES:
        master.wait_for_node(node, timeout=60)
    assert node_pid(master, SLAM) == mapping["pid"], "SLAM was restarted"
    latched = master.probe.wait_for_message("/map", GRID, timeout=30, start=0)
    before = known_cells(mapping["before"])
    assert len(before & known_cells(latched)) >= 0.98 * len(before), "the map from before the restart is gone"
    assert master.param(f"{SLAM}/map_update_interval") == 2.0  # its private parameters are back
    assert master.probe.call("/dynamic_map", timeout=30)["map"]["info"]["width"] > 0


def test_scans_and_odometry_flow_into_slam_again_and_the_map_grows(mapping):
    master = mapping["master"]
    master.wait_for_node("/simulator", timeout=60)
    probe = master.probe
    before = known_cells(mapping["before"])
    probe.subscribe("/map", GRID)
    start = probe.count("/map")
    drive(probe, 0.15, 0.0, 4.0)  # the simulator hears a new publisher: it registered again
    drive(probe, 0.0, 1.0, 3.0)
    drive(probe, 0.0, 0.0, 0.5)
    grown = probe.wait_for_message("/map", GRID, timeout=60, start=start,
                                   where=lambda grid: len(known_cells(grid) - before) > 200)
    assert len(before & known_cells(grown)) >= 0.95 * len(before)
    probe.transform("map", "odom", timeout=10)  # SLAM's map -> odom, through the new master's graph


def test_stopping_mapping_after_the_restart_saves_the_map_and_the_bag_holds_both_sides(mapping):
    master, folder = mapping["master"], mapping["folder"]
    master.wait_for_node(SLAM, timeout=60)
    env = dict(master.env, SNAP_COMMON=str(folder / "common"))
    saved = subprocess.run(["bash", str(REPO / "snap" / "local" / "save_map.sh")], env=env, capture_output=True,
                           text=True, timeout=60)
    assert saved.returncode == 0, saved.stdout + saved.stderr
    image = read_pnm(folder / "common" / "maps" / "new_map.pgm")  # the YAML names it once installed
    assert np.count_nonzero(image != UNKNOWN_PIXEL) >= 0.95 * len(known_cells(mapping["before"]))
    mapping["launch"].stop()
    bag = folder / "session.bag"
    wait_until(bag.exists, 30, lambda: f"no closed bag in {os.listdir(folder)}")
    with Reader(str(bag)) as reader:
        stamps = {topic: [stamp * 1e-9 for connection, stamp, _ in reader.messages() if connection.topic == topic]
                  for topic in ("/scan", "/tf_static")}
    restarted = mapping["restarted"]
    assert sum(stamp < restarted for stamp in stamps["/scan"]) > 10
    assert sum(stamp > restarted + 5.0 for stamp in stamps["/scan"]) > 10, "no scans recorded after the restart"
    # robot_state_publisher was restarted by its guard: the recorder found the new one through the new master
    assert any(stamp > restarted for stamp in stamps["/tf_static"]), "the recorder missed a publisher started since"
