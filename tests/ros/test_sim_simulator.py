"""The simulator node through its launch file, from the install space: Gazebo's TurtleBot3 topics and frames."""
import math

import pytest

from testkit.ros_harness import wait_until

TWIST = "geometry_msgs/Twist"
ODOMETRY = "nav_msgs/Odometry"


@pytest.fixture(scope="module")
def simulator(ros_master):
    ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "model:=waffle_pi", "noise:=none", "seed:=4")
    ros_master.wait_for_node("/simulator", timeout=30)
    ros_master.wait_for_publisher("/scan", timeout=30)
    return ros_master


def test_scan_is_360_beams_in_base_scan_and_sees_the_world(simulator):
    scan = simulator.probe.wait_for_message("/scan", "sensor_msgs/LaserScan", timeout=20)
    assert scan["header"]["frame_id"] == "base_scan"
    assert len(scan["ranges"]) == 360 and scan["angle_min"] == 0.0
    assert scan["angle_increment"] == pytest.approx(2 * math.pi / 360)
    assert (scan["range_min"], scan["range_max"]) == pytest.approx((0.12, 3.5))
    finite = [r for r in scan["ranges"] if math.isfinite(r)]
    assert len(finite) > 200 and all(0.0 < r <= 3.5 for r in finite)
    # At the spawn pose (-2.0, -0.5, 0) a waffle's LIDAR (0.064 m behind base_footprint) sees the
    # wall's inner face behind it at x = -2.933 + 0.5 / tan(60 deg).
    behind = -2.933 + 0.5 / math.tan(math.radians(60))
    assert scan["ranges"][180] == pytest.approx(-2.0 - 0.064 - behind, abs=0.01)


def test_odometry_tf_joint_states_and_imu_use_gazebos_names(simulator):
    probe = simulator.probe
    odom = probe.wait_for_message("/odom", ODOMETRY, timeout=20)
    assert (odom["header"]["frame_id"], odom["child_frame_id"]) == ("odom", "base_footprint")
    assert odom["pose"]["pose"]["position"]["x"] == pytest.approx(-2.0, abs=0.01)
    transform = probe.transform("odom", "base_footprint", timeout=10)
    assert transform["transform"]["translation"]["x"] == pytest.approx(-2.0, abs=0.01)
    joints = probe.wait_for_message("/joint_states", "sensor_msgs/JointState", timeout=20)
    assert joints["name"] == ["wheel_left_joint", "wheel_right_joint"]
    imu = probe.wait_for_message("/imu", "sensor_msgs/Imu", timeout=20)
    assert imu["header"]["frame_id"] == "imu_link"
    assert imu["linear_acceleration"]["z"] == pytest.approx(9.80665)


def test_topics_come_at_gazebos_rates(simulator):
    probe = simulator.probe
    for topic, kind in (("/odom", ODOMETRY), ("/scan", "sensor_msgs/LaserScan")):
        probe.subscribe(topic, kind)
    wait_until(lambda: probe.count("/scan") >= 8, 30, "too few scans")
    stamps = {topic: [m["header"]["stamp"] for m in probe.messages(topic)] for topic in ("/odom", "/scan")}
    scan_period = (stamps["/scan"][-1] - stamps["/scan"][0]) / (len(stamps["/scan"]) - 1)
    odom_period = (stamps["/odom"][-1] - stamps["/odom"][0]) / (len(stamps["/odom"]) - 1)
    assert scan_period == pytest.approx(0.2, rel=0.1)  # stamps, not arrival times: the simulator's schedule
    assert odom_period == pytest.approx(1 / 30, rel=0.15)


def test_cmd_vel_drives_the_robot_and_odometry_follows_ground_truth(simulator):
    probe = simulator.probe
    probe.subscribe("/sim/ground_truth", ODOMETRY)
    probe.publish("/cmd_vel", TWIST, {"linear": {"x": 0.2}})
    moved = probe.wait_for_message(
        "/sim/ground_truth", ODOMETRY, timeout=20, where=lambda m: m["pose"]["pose"]["position"]["x"] > -1.8)
    assert moved["header"]["frame_id"] == "world"
    probe.publish("/cmd_vel", TWIST, {})
    stopped = probe.wait_for_message("/sim/ground_truth", ODOMETRY, timeout=20,
                                     where=lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
    odom = probe.wait_for_message("/odom", ODOMETRY, timeout=20,
                                  where=lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
    assert odom["pose"]["pose"]["position"]["x"] == pytest.approx(stopped["pose"]["pose"]["position"]["x"], abs=1e-6)


def test_teleport_moves_only_the_ground_truth(simulator):
    probe = simulator.probe
    odom_before = probe.wait_for_message("/odom", ODOMETRY, timeout=20)
    probe.publish("/sim/teleport", "geometry_msgs/Pose2D", {"x": -2.0, "y": 0.5, "theta": 0.0})
    truth = probe.wait_for_message("/sim/ground_truth", ODOMETRY, timeout=20,
                                   where=lambda m: m["pose"]["pose"]["position"]["y"] > 0.4)
    assert truth["pose"]["pose"]["position"]["y"] == pytest.approx(0.5)
    odom = probe.wait_for_message("/odom", ODOMETRY, timeout=20)
    assert odom["pose"]["pose"]["position"]["y"] == pytest.approx(odom_before["pose"]["pose"]["position"]["y"])


def test_house_world_and_spawn_pose_args(make_master):
    master = make_master()
    master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=house", "x_pos:=1.5", "y_pos:=2.0",
                  "yaw:=1.57", "model:=burger")
    truth = master.probe.wait_for_message("/sim/ground_truth", ODOMETRY, timeout=30)
    position = truth["pose"]["pose"]["position"]
    assert (position["x"], position["y"]) == pytest.approx((1.5, 2.0))
    assert 2 * math.atan2(truth["pose"]["pose"]["orientation"]["z"], truth["pose"]["pose"]["orientation"]["w"]) \
        == pytest.approx(1.57)


def test_unknown_world_stops_the_launch_with_a_clear_message(make_master):
    master = make_master()
    launch = master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=moon_base")
    wait_until(lambda: not launch.running(), 60, "the launch kept running with an unknown world")
    assert "unknown world 'moon_base'; known worlds:" in launch.log_text()


def test_publish_clock_runs_the_node_on_simulated_time(make_master):
    master = make_master()
    master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "publish_clock:=true", "world:=empty")
    clock = master.probe.wait_for_message("/clock", "rosgraph_msgs/Clock", timeout=30,
                                          where=lambda m: m["clock"] > 0.5)
    scan = master.probe.wait_for_message("/scan", "sensor_msgs/LaserScan", timeout=30)
    # Simulated seconds since the simulator started, not the wall clock's 1.7e9.
    assert clock["clock"] < 100 and 0.5 < scan["header"]["stamp"] < 100


@pytest.mark.parametrize("parameter, expected", [
    ("_x_pos:=nan", "parameter ~x_pos must be a finite number, got nan"),
    ("_x_pos:=left", "parameter ~x_pos must be a number, got 'left'"),
    ("_rate:=0", "parameter ~rate must be more than 0, got 0"),
    ("_publish_clock:=maybe", "parameter ~publish_clock must be true or false, got 'maybe'"),
])
def test_a_parameter_the_simulator_cannot_run_with_stops_it_with_one_line(ros_master, parameter, expected):
    status, log = ros_master.rosrun_refused("turtlebot3c_sim", "simulator", parameter)
    assert status == 2
    assert expected in log and "Traceback" not in log
