"""The fake_robot executable from the install space: runs without a ROS master, driven over its control socket."""
import signal

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler, PortHandler

from testkit import ros_harness
from testkit.ros_harness import wait_until
from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_sim.fake_robot import ControlError, send_command


def start_fake_robot(env, workdir, *extra):
    args = ["rosrun", "turtlebot3c_sim", "fake_robot",
            "--opencr-link", workdir / "dev" / "ttyACM0", "--lds-link", workdir / "dev" / "ttyUSB0",
            "--lds-model", "LDS-02", "--model", "waffle_pi", "--world", "turtlebot3_world", "--seed", "3",
            "--control-socket", workdir / "control"] + list(extra)
    return ros_harness.Process(args, env, workdir / "fake_robot.log")


@pytest.fixture(scope="module")
def fake_robot(ros_env, tmp_path_factory):
    workdir = tmp_path_factory.mktemp("fake_robot")
    env = dict(ros_env, ROS_MASTER_URI=f"http://127.0.0.1:{ros_harness.free_port()}")  # nobody there
    process = start_fake_robot(env, workdir)
    wait_until(lambda: "ready" in process.log_text() or not process.running(), 30,
               lambda: f"fake_robot did not start:\n{process.log_text()}")
    assert process.running(), process.log_text()
    yield process, workdir
    process.stop()


def ping(path):
    """Ping as a driver would: a reply that missed the SDK's ~35 ms deadline on a busy machine is retried."""
    port = PortHandler(str(path))
    try:
        assert port.openPort() and port.setBaudRate(table.BAUD_RATE)
        for _ in range(3):
            answer = PacketHandler(2.0).ping(port, table.DEVICE_ID)
            if answer[1] != COMM_RX_TIMEOUT:
                break
        return answer
    finally:
        port.closePort()


def test_runs_without_a_master_and_answers_on_both_links(fake_robot):
    _, workdir = fake_robot
    assert ping(workdir / "dev" / "ttyACM0")[:2] == (0x5000, COMM_SUCCESS)
    with open(workdir / "dev" / "ttyUSB0", "rb", buffering=0) as lidar:
        assert lidar.read(512)
    status = send_command(workdir / "control", "status")
    assert status["model"] == "waffle_pi" and status["world"] == "turtlebot3_world"
    assert status["pose"][:2] == pytest.approx([-2.0, -0.5])
    assert status["devices"]["lds"]["model"] == "LDS-02"


def test_unplug_and_replug_from_another_process(fake_robot):
    _, workdir = fake_robot
    control, link = workdir / "control", workdir / "dev" / "ttyACM0"
    assert send_command(control, "unplug opencr") is None
    assert not link.exists()
    assert send_command(control, "status")["devices"]["opencr"]["plugged"] is False
    send_command(control, "replug opencr")
    assert ping(link)[:2] == (0x5000, COMM_SUCCESS)
    send_command(control, "unplug lds")
    assert not (workdir / "dev" / "ttyUSB0").exists()
    send_command(control, "replug lds")
    assert (workdir / "dev" / "ttyUSB0").exists()


def test_faults_are_set_and_cleared_over_the_socket(fake_robot):
    _, workdir = fake_robot
    control = workdir / "control"
    send_command(control, "faults opencr crc=1.0")
    assert ping(workdir / "dev" / "ttyACM0")[1] != COMM_SUCCESS
    send_command(control, "faults opencr none")
    assert ping(workdir / "dev" / "ttyACM0")[1] == COMM_SUCCESS
    assert send_command(control, "status")["devices"]["opencr"]["faults_injected"]["crc"] >= 1


def test_bad_control_commands_say_what_is_wrong(fake_robot):
    control = fake_robot[1] / "control"
    with pytest.raises(ControlError, match="unknown fault 'crcs'"):
        send_command(control, "faults opencr crcs=0.1")
    with pytest.raises(ControlError, match="no device 'camera'"):
        send_command(control, "unplug camera")
    with pytest.raises(ControlError, match="try help"):
        send_command(control, "fly")
    with pytest.raises(ControlError, match="overlaps an obstacle"):
        send_command(control, "teleport 0 0 0")
    assert "unplug" in send_command(control, "help")


def test_teleport_moves_the_ground_truth(fake_robot):
    control = fake_robot[1] / "control"
    send_command(control, "teleport -2.0 0.5 1.0")
    assert send_command(control, "pose") == pytest.approx([-2.0, 0.5, 1.0])
    send_command(control, "teleport -2.0 -0.5 0.0")


def test_bad_arguments_fail_with_a_clear_message(ros_env, tmp_path):
    process = start_fake_robot(ros_env, tmp_path, "--world", "moon_base")
    assert process.wait(30) == 2
    assert "unknown world 'moon_base'; known worlds:" in process.log_text()
    process = start_fake_robot(ros_env, tmp_path, "--faults", "opencr:crc=2")
    assert process.wait(30) == 2
    assert "must be a probability" in process.log_text()


def test_sigterm_stops_it_and_removes_the_links(ros_env, tmp_path):
    process = start_fake_robot(ros_env, tmp_path)
    wait_until(lambda: "ready" in process.log_text(), 30, lambda: process.log_text())
    process.popen.send_signal(signal.SIGTERM)  # rosrun execs the node: this is the node itself
    assert process.wait(10) == 0
    assert not (tmp_path / "dev" / "ttyACM0").exists() and not (tmp_path / "control").exists()


def test_ground_truth_is_published_when_asked(ros_master, tmp_path):
    process = start_fake_robot(ros_master.env, tmp_path, "--publish-ground-truth", "--x", "-2.0", "--y", "0.5")
    ros_master.processes.append(process)
    message = ros_master.probe.wait_for_message("/sim/ground_truth", "nav_msgs/Odometry", timeout=30)
    assert message["header"]["frame_id"] == "world" and message["child_frame_id"] == "base_footprint"
    assert message["pose"]["pose"]["position"]["x"] == pytest.approx(-2.0)
    assert message["pose"]["pose"]["position"]["y"] == pytest.approx(0.5)
