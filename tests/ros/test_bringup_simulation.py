"""turtlebot3c_bringup.launch with simulation:=true, from the install space, beside the simulator.

What upstream's snap CI checks (scan and joint_states flowing, /tf, node
robot_state_publisher), plus: no hardware driver runs, and the model's frames
join the simulator's odometry in one tf tree.
"""
import pytest

ODOMETRY = "nav_msgs/Odometry"
SCAN = "sensor_msgs/LaserScan"
JOINTS = "sensor_msgs/JointState"


@pytest.fixture(scope="module")
def simulated(ros_master):
    ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "model:=waffle_pi")
    ros_master.launch("turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=true", "model:=waffle_pi")
    ros_master.wait_for_node("/robot_state_publisher", timeout=60)
    return ros_master


def test_scan_joint_states_and_tf_flow_with_robot_state_publisher_running(simulated):
    probe = simulated.probe
    assert probe.wait_for_message("/scan", SCAN, timeout=30)["header"]["frame_id"] == "base_scan"
    joints = probe.wait_for_message("/joint_states", JOINTS, timeout=30)
    assert set(joints["name"]) == {"wheel_left_joint", "wheel_right_joint"}
    assert "/robot_state_publisher" in simulated.publishers("/tf_static")
    simulated.wait_for_publisher("/tf")


def test_only_the_model_runs_no_hardware_driver(simulated):
    nodes = simulated.node_names()
    assert "/robot_state_publisher" in nodes
    assert not {"/turtlebot3_core", "/turtlebot3_lds"} & nodes
    assert "turtlebot3_waffle_pi" in simulated.param("/robot_description")
    assert simulated.param("/robot_state_publisher/publish_frequency") == 50.0


def test_the_model_frames_hang_below_the_simulated_odometry(simulated):
    probe = simulated.probe
    scan = probe.transform("base_footprint", "base_scan", timeout=10)["transform"]["translation"]
    assert (scan["x"], scan["y"], scan["z"]) == (pytest.approx(-0.064), pytest.approx(0.0), pytest.approx(0.132))
    probe.transform("odom", "base_scan", timeout=10)
    camera = probe.transform("base_link", "camera_rgb_optical_frame", timeout=10)["transform"]["translation"]
    assert camera["x"] == pytest.approx(0.076)
    wheel = probe.transform("base_link", "wheel_right_link", timeout=10)["transform"]["translation"]
    assert wheel["y"] == pytest.approx(-0.144)
