"""Recognising ROBOTIS's ROS 1 OpenCR firmware: rosserial frames, its topic list and its version message."""
import errno
import struct

import serial

from turtlebot3c_bringup import rosserial_frames as frames
from turtlebot3c_bringup.serial_errors import RAW_USB_FIX, explain_open_error
from turtlebot3c_sim import fake_rosserial


def test_the_topic_request_is_rosserials_own():
    assert frames.REQUEST_TOPICS == bytes.fromhex("fffe0000ff0000ff")
    assert frames.STOP_SENDING == bytes.fromhex("fffe0000ff0b00f4")


def test_the_fake_firmwares_answer_parses_to_its_topics_and_version():
    board = fake_rosserial.RosserialFirmware()
    reply = board.receive(b"noise" + frames.REQUEST_TOPICS, now=0.0) + board.due(now=0.0)
    parser = frames.FrameParser()
    received = []
    for start in range(0, len(reply), 7):  # in pieces, as a serial port delivers them
        received += parser.feed(reply[start:start + 7])
    names = {info.name: info.topic_id for info in frames.topic_infos(received)}
    assert {"firmware_version", "cmd_vel", "odom"} <= set(names)
    version = [item for item in received if item.topic_id == names["firmware_version"]]
    assert [frames.decode_version_info(item.payload) for item in version] == ["1.2.6"]


def test_frames_with_a_bad_checksum_and_noise_are_skipped():
    good = frames.frame(125, b"abc")
    bad = bytearray(good)
    bad[-1] ^= 0xFF
    parser = frames.FrameParser()
    assert parser.feed(b"\xff\xff\xfe\x01" + bytes(bad) + good) == [frames.Frame(125, b"abc")]
    assert parser.frames_accepted == 1


def test_a_dynamixel_status_packet_is_no_rosserial_frame():
    parser = frames.FrameParser()
    assert parser.feed(bytes.fromhex("fffffd00c8070055000050050d6c")) == []


def test_a_truncated_version_message_is_not_decoded():
    assert frames.decode_version_info(struct.pack("<I", 50) + b"short") is None


def test_open_errors_say_absent_or_the_raw_usb_connection():
    denied = serial.SerialException(errno.EACCES, "could not open port /dev/ttyACM0: [Errno 13] Permission denied")
    problem = explain_open_error("/dev/ttyACM0", denied, "OpenCR", "opencr-port")
    assert problem.message == "not permitted to open /dev/ttyACM0 (the OpenCR's serial port)"
    assert problem.fix == RAW_USB_FIX == "sudo snap connect turtlebot3c:raw-usb"
    absent = explain_open_error("/dev/ttyUSB0", FileNotFoundError(errno.ENOENT, "No such file"), "LIDAR", "lds-port")
    assert absent.message == "no LIDAR at /dev/ttyUSB0"
    assert absent.fix == "plug the LIDAR in, or set its port: sudo snap set turtlebot3c lds-port=/dev/..."


def test_the_fake_board_cuts_its_motors_after_5_s_below_11_volts_and_restores_them_above():
    from turtlebot3c_sim.fake_opencr import FakeOpenCR
    from turtlebot3c_sim.simulation import NoiseConfig, Simulation
    from turtlebot3c_sim.world import load_world

    sim = Simulation(load_world("empty"), model="burger", pose=(0.0, 0.0, 0.0), noise=NoiseConfig.none())
    board = FakeOpenCR(sim)
    board.battery_voltage = 10.8
    for _ in range(40):  # 4 s: not yet
        sim.step(0.1)
        board.update()
    assert board.motor_power
    for _ in range(15):
        sim.step(0.1)
        board.update()
    assert not board.motor_power
    board.battery_voltage = 11.5
    board.update()
    assert board.motor_power
