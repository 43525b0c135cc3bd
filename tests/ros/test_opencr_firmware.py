"""The OpenCR driver names the firmware it finds when the board ignores DYNAMIXEL pings.

The fake robot's OpenCR runs ROBOTIS's ROS 1 rosserial firmware here (it talks only at
115200 baud), or the ROS 2 firmware after a `firmware dynamixel` flash.
"""
import time

import pytest

from testkit.recording_log import RecordingLog
from testkit.ros_harness import wait_until
from turtlebot3c_bringup.opencr_diagnostics import TO_DO, link_status
from turtlebot3c_bringup.opencr_driver import OpenCRDriver
from turtlebot3c_bringup.opencr_firmware import listen_for_rosserial
from turtlebot3c_bringup.opencr_link import OpenCRLink
from turtlebot3c_common.backoff import Backoff
from turtlebot3c_description.models import get_model
from turtlebot3c_sim.fake_robot import RealTimeRobot
from turtlebot3c_sim.simulation import NoiseConfig


@pytest.fixture
def rosserial_board(tmp_path):
    robot = RealTimeRobot(world="empty", model="burger", pose=(0.0, 0.0, 0.0), noise=NoiseConfig.none(),
                          opencr_link=tmp_path / "ttyACM0", opencr_firmware="rosserial").start()
    yield robot
    robot.stop()


def test_listening_at_115200_finds_the_rosserial_firmware_and_its_version(rosserial_board):
    found = listen_for_rosserial(str(rosserial_board.devices["opencr"].link.path))
    assert found is not None
    assert found.version == "1.2.6" and found.baud == 115200
    assert "rosserial" in found.describe()


def test_the_ros2_firmware_is_not_taken_for_rosserial(rosserial_board):
    rosserial_board.execute("firmware dynamixel")
    assert listen_for_rosserial(str(rosserial_board.devices["opencr"].link.path), listen_time=1.5) is None


def test_the_driver_names_the_rosserial_firmware_within_seconds_then_connects_once_flashed(rosserial_board):
    log = RecordingLog()
    driver = OpenCRDriver(OpenCRLink(str(rosserial_board.devices["opencr"].link.path)), get_model("burger"),
                          log=log, backoff=Backoff(0.05, 0.3), firmware_probe=listen_for_rosserial)
    start = time.monotonic()
    try:
        while not any(level == "error" for level, _ in log.lines) and time.monotonic() - start < 10:
            driver.cycle()
            time.sleep(0.02)
        detected = time.monotonic() - start
        errors = [message for level, message in log.lines if level == "error"]
        assert errors, f"no error naming the firmware: {log.lines}"
        assert detected < 10.0
        print(f"rosserial firmware named after {detected:.1f} s: {errors[0]}")
        assert "ROS 1 rosserial firmware 1.2.6 at 115200 baud" in errors[0]
        assert "DYNAMIXEL protocol 2.0, ID 200, 1 Mbps" in errors[0] and "update.sh" in errors[0]
        status = link_status(driver, "/dev/ttyACM0", 1000000)
        assert "rosserial" in status.message and "update.sh" in status.values[TO_DO]
        # Retries go on without listening again (and without repeating the error) until the interval is over.
        for _ in range(50):
            driver.cycle()
            time.sleep(0.02)
        assert len([level for level, _ in log.lines if level == "error"]) == 1
        rosserial_board.execute("firmware dynamixel")
        wait_until(lambda: driver.cycle() is not None or driver.connected, 10, lambda: f"never connected: {log.lines}")
        assert driver.other_firmware is None and driver.fix == ""
    finally:
        driver.shutdown()
