"""The mapping launch against the simulator: map, tf, map_saver, the session bag, offline re-mapping."""
import math
import re
import subprocess
import time

import numpy as np
import pytest

from testkit import ros_harness
from turtlebot3c_maps.map_files import OccupancyMap, load_map
from turtlebot3c_sim.evaluation import cell_agreement, occupied_precision
from turtlebot3c_sim.world import load_world

GRID = "nav_msgs/OccupancyGrid"
TWIST = "geometry_msgs/Twist"


def grid_map(message):
    info = message["info"]
    q = info["origin"]["orientation"]
    yaw = math.atan2(2.0 * (q["w"] * q["z"] + q["x"] * q["y"]), 1.0 - 2.0 * (q["y"] ** 2 + q["z"] ** 2))
    return OccupancyMap.from_message(message["data"], info["width"], info["height"], info["resolution"],
                                     (info["origin"]["position"]["x"], info["origin"]["position"]["y"], yaw))


def truth_of(occupancy_map, world):
    return world.rasterize(occupancy_map.resolution, occupancy_map.origin[:2], occupancy_map.width,
                           occupancy_map.height)


def has_param(master, name):
    try:
        master.param(name)
        return True
    except KeyError:
        return False


def common_window(first, second):
    """Both maps' cells over the part of the grid lattice they share (same resolution)."""
    low1 = np.zeros(2, dtype=int)
    low2 = np.round((np.array(second.origin[:2]) - first.origin[:2]) / first.resolution).astype(int)
    low = np.maximum(low1, low2)
    high = np.minimum(low1 + (first.width, first.height), low2 + (second.width, second.height))
    return (first.data[low[1] - low1[1]:high[1] - low1[1], low[0] - low1[0]:high[0] - low1[0]],
            second.data[low[1] - low2[1]:high[1] - low2[1], low[0] - low2[0]:high[0] - low2[0]])


def run(ros_master, *args, timeout=60):
    return subprocess.run([str(a) for a in args], env=ros_master.env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(scope="module")
def session(ros_master, tmp_path_factory):
    """Simulator + robot model (for the LIDAR mount) + mapping launch; the robot turns and creeps forward."""
    folder = tmp_path_factory.mktemp("mapping")
    simulator = ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=turtlebot3_world",
                                  "model:=burger")
    ros_master.launch("turtlebot3c_description", "description.launch", "model:=burger")
    ros_harness.wait_until(lambda: has_param(ros_master, "/robot_description"), 60, "no robot_description")
    ros_master.rosrun("robot_state_publisher", "robot_state_publisher")
    ros_master.wait_for_publisher("/scan", timeout=60)
    mapping = ros_master.launch("turtlebot3c_slam", "turtlebot3c_mapping.launch", "model:=burger",
                                f"bag:={folder / 'session.bag'}")
    ros_master.wait_for_node("/turtlebot3_slam_gmapping", timeout=60)
    probe = ros_master.probe
    probe.subscribe("/map", GRID)
    probe.wait_for_message("/map", GRID, timeout=60, start=0)
    for command in ([0.0, 1.0], [0.08, 0.0], [0.0, -1.0]):
        started = time.monotonic()
        while time.monotonic() - started < 4.0:
            probe.publish("/cmd_vel", TWIST, {"linear": {"x": command[0]}, "angular": {"z": command[1]}})
            time.sleep(0.1)
    probe.publish("/cmd_vel", TWIST, {})
    return {"folder": folder, "simulator": simulator, "mapping": mapping, "master": ros_master}


def test_slam_runs_under_upstream_node_name_and_publishes_latched_map_with_metadata(session):
    master = session["master"]
    assert "/turtlebot3_slam_gmapping" in master.node_names()
    grid = master.probe.wait_for_message("/map", GRID, start=0)
    assert grid["header"]["frame_id"] == "map"
    assert grid["info"]["resolution"] == pytest.approx(0.05)
    metadata = master.probe.wait_for_message("/map_metadata", "nav_msgs/MapMetaData", start=0)
    published = {(m["info"]["width"], m["info"]["height"]) for m in master.probe.messages("/map")}
    assert (metadata["width"], metadata["height"]) in published
    assert metadata["resolution"] == pytest.approx(0.05)


def test_live_map_matches_the_simulated_world(session):
    master = session["master"]
    latest = master.probe.messages("/map")[-1]
    occupancy_map = grid_map(latest)
    truth = truth_of(occupancy_map, load_world("turtlebot3_world"))
    assert (occupancy_map.data == 100).sum() > 100
    assert cell_agreement(occupancy_map.data, truth) >= 0.95
    assert occupied_precision(occupancy_map.data, truth) >= 0.95


def test_map_updates_are_rate_bounded(session):
    master = session["master"]
    stamps = [message["header"]["stamp"] for message in master.probe.messages("/map")]
    assert len(stamps) >= 2
    assert np.diff(stamps).min() >= 2.0 - 0.01  # map_update_interval 2.0 s, not once per scan (5 Hz)


def test_map_to_odom_transform_is_published(session):
    transform = session["master"].probe.transform("map", "odom", timeout=10.0)
    translation = transform["transform"]["translation"]
    assert math.hypot(translation["x"], translation["y"]) < 0.5  # odometry drifts little in seconds


def test_map_saver_writes_the_published_map(session):
    master, prefix = session["master"], session["folder"] / "saved"
    result = run(master, "rosrun", "turtlebot3c_maps", "map_saver", "-f", prefix)
    assert result.returncode == 0, result.stderr
    saved = load_map(f"{prefix}.yaml")
    latest = grid_map(master.probe.messages("/map")[-1])
    assert saved.origin == pytest.approx(latest.origin)
    assert saved.data.shape == latest.data.shape
    assert (saved.data == 100).sum() > 0


def test_refine_map_says_what_it_refined_and_publishes_the_refined_map(session):
    # mapping's stop-command calls it, then map_saver takes the latched map (the offline test below
    # compares that map with remap_bag's).
    master = session["master"]
    probe = master.probe
    before = probe.count("/map")
    response = probe.call("/refine_map", timeout=60)
    assert response["success"], response
    assert re.fullmatch(r"map refined: \d+ keyframes against the scans near each, in \d+\.\d s", response["message"])
    refined = probe.wait_for_message("/map", GRID, start=before, timeout=10)
    assert refined["header"]["stamp"] > probe.messages("/map")[before - 1]["header"]["stamp"]
    occupancy_map = grid_map(refined)
    truth = truth_of(occupancy_map, load_world("turtlebot3_world"))
    assert cell_agreement(occupancy_map.data, truth) >= 0.95
    assert occupied_precision(occupancy_map.data, truth) >= 0.95


def test_a_scan_without_beams_is_skipped_with_a_warning_not_a_traceback(session):
    master = session["master"]
    for _ in range(3):
        master.probe.publish("/scan", "sensor_msgs/LaserScan", {"header": {"frame_id": "base_scan"}})
    logs = master.workdir / "ros_log"

    def node_log():
        # The SLAM node's own logs only: map_saver's shutdown may log rospy's own socket traceback.
        return "".join(path.read_text(errors="replace") for path in logs.rglob("turtlebot3_slam_gmapping*.log"))
    ros_harness.wait_until(lambda: "slam: scan at 0.000 skipped: a scan needs at least one beam" in node_log(), 20,
                           "the SLAM node did not say it skipped the scan without beams")
    assert "Traceback" not in node_log()
    master.wait_for_node("/turtlebot3_slam_gmapping", timeout=10)


def test_offline_remapping_of_the_session_bag_gives_the_live_map(session):
    master, folder = session["master"], session["folder"]
    session["simulator"].stop()  # no more scans
    # The last scans' keyframes reach /map within one map_update_interval (2 s); nothing observable
    # tells "no newer map is coming", so this one wait is a fixed one.
    time.sleep(3.0)
    assert master.probe.call("/refine_map", timeout=60)["success"]  # the map as mapping's stop saves it
    live_prefix = folder / "live"
    saved = run(master, "rosrun", "turtlebot3c_maps", "map_saver", "-f", live_prefix)
    assert saved.returncode == 0, saved.stderr
    session["mapping"].stop()  # SIGINT: rosbag closes the bag
    bag = folder / "session.bag"
    ros_harness.wait_until(bag.exists, 20, f"no bag at {bag}: {sorted(p.name for p in folder.iterdir())}")
    offline_prefix = folder / "offline"
    result = run(master, "rosrun", "turtlebot3c_slam", "remap_bag", bag, "-o", offline_prefix, timeout=300)
    assert result.returncode == 0, result.stderr
    live, offline = load_map(f"{live_prefix}.yaml"), load_map(f"{offline_prefix}.yaml")
    trajectory = np.loadtxt(f"{offline_prefix}_trajectory.txt")
    assert trajectory.shape[1] == 4 and len(trajectory) > 20
    # Same frame and, cell for cell where both saw something, the same map.
    a, b = common_window(offline, live)
    both = (a >= 0) & (b >= 0)
    assert both.sum() > 0.9 * min((a >= 0).sum(), (b >= 0).sum())
    assert (a[both] == b[both]).mean() >= 0.99
