"""Listening for a LIDAR model on a port: the fake LIDAR answers only as the model it is, at its baud rate."""
import pytest

from turtlebot3c_bringup.lds_model_check import WrongModel, listen_for, other_models
from turtlebot3c_sim.fake_robot import RealTimeRobot
from turtlebot3c_sim.simulation import NoiseConfig


@pytest.fixture(params=["LDS-01", "LDS-02"])
def lidar(request, tmp_path):
    robot = RealTimeRobot(world="turtlebot3_world", model="burger", noise=NoiseConfig.none(),
                          lds_link=tmp_path / "ttyUSB0", lds_model=request.param).start()
    yield robot, request.param
    robot.stop()


def test_only_the_model_on_the_port_is_heard(lidar):
    robot, model = lidar
    port = str(robot.devices["lds"].link.path)
    (other,) = other_models(model)
    assert listen_for(port, model)
    assert not listen_for(port, other)


def test_a_swapped_lidar_is_heard_as_the_new_model(lidar):
    robot, model = lidar
    (other,) = other_models(model)
    assert robot.execute(f"lidar {other}") == "ok"
    assert listen_for(str(robot.devices["lds"].link.path), other)


def test_the_message_names_the_model_found_and_the_snap_set_that_fixes_it():
    wrong = WrongModel("LDS-01", "LDS-02", "/dev/ttyUSB0")
    assert wrong.message == "no scans: the LIDAR on /dev/ttyUSB0 streams LDS-02 packets, but lds-model is LDS-01"
    assert wrong.fix == "sudo snap set turtlebot3c lds-model=LDS-02"
