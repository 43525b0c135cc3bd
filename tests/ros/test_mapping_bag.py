"""Offline re-mapping (remap_bag) of ROS 1 bags written with rosbags from simulator runs; no ROS master."""
import math
import subprocess

import numpy as np
import pytest
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from testkit import ros_harness
from testkit.damaged_bag import with_frame_names_not_utf8
from turtlebot3c_common.bag_inputs import read_trajectory
from turtlebot3c_maps.map_files import load_map
from turtlebot3c_sim.evaluation import ROUTES, absolute_trajectory_error, cell_agreement, drive_route
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world

SCAN, ODOM, TF = "sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage"


def typestore():
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))
    return store


class BagBuilder:
    def __init__(self, store):
        self.store = store
        self.types = store.types

    def header(self, stamp, frame):
        seconds = int(stamp)
        time = self.types["builtin_interfaces/msg/Time"](sec=seconds, nanosec=int(round((stamp - seconds) * 1e9)))
        return self.types["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)

    def pose_parts(self, x, y, z, yaw):
        types = self.types
        return (types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
                types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)))

    def transform(self, stamp, parent, child, x, y, z, yaw):
        translation, rotation = self.pose_parts(x, y, z, yaw)
        return self.types["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent), child_frame_id=child,
            transform=self.types["geometry_msgs/msg/Transform"](translation=translation, rotation=rotation))

    def tf(self, transforms):
        return self.types[TF](transforms=transforms)

    def scan(self, stamp, frame, scan):
        return self.types[SCAN](
            header=self.header(stamp, frame), angle_min=scan.angle_min, angle_max=scan.angle_max,
            angle_increment=scan.angle_increment, time_increment=0.0, scan_time=0.0, range_min=scan.range_min,
            range_max=scan.range_max, ranges=np.asarray(scan.ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32))

    def odometry(self, stamp, pose):
        types = self.types
        position, orientation = self.pose_parts(pose[0], pose[1], 0.0, pose[2])
        covariance = np.zeros(36)
        return types[ODOM](
            header=self.header(stamp, "odom"), child_frame_id="base_footprint",
            pose=types["geometry_msgs/msg/PoseWithCovariance"](
                pose=types["geometry_msgs/msg/Pose"](
                    position=types["geometry_msgs/msg/Point"](x=position.x, y=position.y, z=0.0),
                    orientation=orientation), covariance=covariance),
            twist=types["geometry_msgs/msg/TwistWithCovariance"](
                twist=types["geometry_msgs/msg/Twist"](linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                                                       angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                covariance=covariance))


def record_run(path, route, scan_topic="/scan", odom_topic="/odom", with_tf=True, start=100.0):
    """Drive turtlebot3_world's route, writing a bag; returns the world and (stamp, true pose) per scan."""
    world = load_world("turtlebot3_world")
    sim = Simulation(world, model="burger", pose=world.spawn_pose, seed=3, noise=NoiseConfig())
    store = typestore()
    build = BagBuilder(store)
    truth = []
    with Writer(path) as writer:
        scans = writer.add_connection(scan_topic, SCAN, typestore=store)
        odoms = writer.add_connection(odom_topic, ODOM, typestore=store)
        tfs = writer.add_connection("/tf", TF, typestore=store) if with_tf else None
        static = writer.add_connection("/tf_static", TF, typestore=store, latching=1) if with_tf else None

        def write(connection, stamp, message, kind):
            writer.write(connection, int(stamp * 1e9), store.serialize_ros1(message, kind))
        if with_tf:
            # A chain, as robot_state_publisher gives it: base_footprint -> base_link -> base_scan.
            mount = sim.model.scan_mount
            write(static, start, build.tf([build.transform(start, "base_footprint", "base_link", 0.0, 0.0, 0.01, 0.0),
                                           build.transform(start, "base_link", "base_scan", mount[0], mount[1], 0.17,
                                                           0.0)]), TF)

        def on_odometry(stamp):
            pose = sim.odometry[:3]
            write(odoms, stamp, build.odometry(stamp, pose), ODOM)
            if with_tf:
                write(tfs, stamp, build.tf([build.transform(stamp, "odom", "base_footprint", pose[0], pose[1], 0.0,
                                                            pose[2])]), TF)

        def on_scan(simulation):
            stamp = start + simulation.time
            on_odometry(stamp)
            write(scans, stamp, build.scan(stamp, "base_scan", simulation.scan()), SCAN)
            truth.append((stamp, simulation.pose))
        assert drive_route(sim, route, 0.2, on_scan, timeout=600)
        on_odometry(start + sim.time + 0.01)
    return world, truth


def remap(ros_env, *args):
    executable = ros_harness.PRIME_ROS / "lib" / "turtlebot3c_slam" / "remap_bag"
    return subprocess.run([str(executable)] + [str(a) for a in args], env=ros_env, capture_output=True, text=True,
                          timeout=600)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bags")
    world, scans = record_run(folder / "session.bag", ROUTES["turtlebot3_world"][:9])
    return folder, world, scans


def test_remapping_a_bag_writes_a_map_matching_the_world_and_the_trajectory_per_scan(ros_env, recorded):
    folder, world, scans = recorded
    result = remap(ros_env, folder / "session.bag")
    assert result.returncode == 0, result.stderr
    assert "odometry from tf" in result.stdout
    occupancy_map = load_map(folder / "session.yaml")
    occupied = world.rasterize(occupancy_map.resolution, occupancy_map.origin[:2], occupancy_map.width,
                               occupancy_map.height)
    assert cell_agreement(occupancy_map.data, occupied) >= 0.95
    trajectory = read_trajectory(folder / "session_trajectory.txt")
    assert [row[0] for row in trajectory] == pytest.approx([stamp for stamp, _ in scans], abs=1e-6)
    assert absolute_trajectory_error([row[1:] for row in trajectory], [pose for _, pose in scans])[0] <= 0.05


def test_odometry_topic_gives_the_same_map_as_tf(ros_env, recorded):
    """Cell for cell, so numpy's AVX-512 sin/cos are off: their last bit varies from run to run
    (ros_harness.SINGLE_CORE_REPRODUCIBLE), and the two maps differed on a fresh machine."""
    folder, _, _ = recorded
    reproducible = dict(ros_env, **ros_harness.SINGLE_CORE_REPRODUCIBLE)
    assert remap(reproducible, folder / "session.bag", "-o", folder / "by_tf").returncode == 0
    result = remap(reproducible, folder / "session.bag", "-o", folder / "by_topic", "--odom-source", "topic")
    assert result.returncode == 0, result.stderr
    assert "odometry from /odom" in result.stdout
    assert np.array_equal(load_map(folder / "by_tf.yaml").data, load_map(folder / "by_topic.yaml").data)


def test_other_topic_names_and_a_bag_without_tf_need_the_mount(ros_env, tmp_path):
    bag = tmp_path / "plain.bag"
    _, scans = record_run(bag, ROUTES["turtlebot3_world"][:3], scan_topic="/lidar/scan",
                              odom_topic="/wheel/odom", with_tf=False)
    missing = remap(ros_env, bag, "--scan-topic", "/lidar/scan", "--odom-topic", "/wheel/odom")
    assert missing.returncode == 1
    assert "no transform from base_footprint to the scan frame base_scan" in missing.stderr
    assert "--scan-mount" in missing.stderr
    result = remap(ros_env, bag, "--scan-topic", "/lidar/scan", "--odom-topic", "/wheel/odom",
                   "--scan-mount=-0.032,0,0", "-o", tmp_path / "plain_map")
    assert result.returncode == 0, result.stderr
    assert "odometry from /wheel/odom" in result.stdout
    assert len(read_trajectory(tmp_path / "plain_map_trajectory.txt")) == len(scans)


def test_bag_without_the_scan_topic_fails_naming_its_topics(ros_env, recorded):
    folder, _, _ = recorded
    result = remap(ros_env, folder / "session.bag", "--scan-topic", "/nothing")
    assert result.returncode == 1
    assert "has no /nothing topic (its topics: /odom, /scan, /tf, /tf_static)" in result.stderr


def test_missing_or_corrupt_bag_fails_clearly(ros_env, tmp_path):
    result = remap(ros_env, tmp_path / "absent.bag")
    assert result.returncode == 1 and "cannot read bag" in result.stderr
    (tmp_path / "junk.bag").write_bytes(b"not a bag at all")
    result = remap(ros_env, tmp_path / "junk.bag")
    assert result.returncode == 1 and "cannot read bag" in result.stderr


@pytest.mark.parametrize("problem, expected", [
    ("damaged bag", "it is damaged or not a ROS 1 bag"),
    ("config not YAML", "is not valid YAML: expected ',' or ']'"),
    ("config not text", "is not a text file of SLAM parameters"),
    ("config a folder", "cannot read SLAM parameters from"),
    ("config number too large", "SLAM parameter resolution must be a finite number, got 1000"),
])
def test_a_damaged_bag_or_a_broken_config_fails_with_one_line(ros_env, recorded, tmp_path, problem, expected):
    folder, _, _ = recorded
    bag, config = folder / "session.bag", tmp_path / "slam.yaml"
    if problem == "damaged bag":
        bag = with_frame_names_not_utf8(folder / "session.bag", tmp_path / "damaged.bag")
        config.write_text("resolution: 0.05\n")
    elif problem == "config a folder":
        config = tmp_path
    else:
        config.write_bytes({"config not YAML": b"resolution: [0.05\n", "config not text": b"\xff\xfe\x00",
                            "config number too large": b"resolution: 1" + b"0" * 400 + b"\n"}[problem])
    result = remap(ros_env, bag, "--config", config, "-o", tmp_path / "map")
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 1 and len(lines) == 1 and lines[0].startswith("remap_bag: "), result.stderr
    assert expected in lines[0]
    assert not (tmp_path / "map.yaml").exists()
