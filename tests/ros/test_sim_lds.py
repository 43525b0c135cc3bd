"""The fake LDS-01 and LDS-02: packets parsed per the byte formats give back the ray-cast ranges."""
import math
import struct
import time

import numpy as np
import pytest
import serial

from testkit.ros_harness import wait_until
from turtlebot3c_sim.fake_lds import BAUD_RATES, Lds01Stream, Lds02Stream
from turtlebot3c_sim.fake_robot import RealTimeRobot
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world

POSE = (-2.0, -0.5, 0.3)


def perfect_sim():
    return Simulation(load_world("turtlebot3_world"), model="burger", pose=POSE, noise=NoiseConfig.none())


# --- LDS-01: 42-byte packets, 60 per revolution -------------------------------------------

def split_lds01(stream_bytes):
    """Packets found as ROBOTIS's driver finds them: 0xFA then 0xA0 + index."""
    packets, i = [], 0
    while i + 42 <= len(stream_bytes):
        if stream_bytes[i] == 0xFA and 0xA0 <= stream_bytes[i + 1] <= 0xDB:
            packets.append(stream_bytes[i:i + 42])
            i += 42
        else:
            i += 1
    return packets


def lds01_checksum_ok(packet):
    expected = (0xFF - sum(packet[:40])) & 0xFF
    return packet[40] == expected and packet[41] == expected


def lds01_ranges(packets):
    ranges = np.full(360, np.nan)
    for packet in packets:
        index = packet[1] - 0xA0
        for k in range(6):
            _intensity, millimetres, _ = struct.unpack_from("<HHH", packet, 4 + 6 * k)
            ranges[359 - (6 * index + k)] = millimetres / 1000.0
    return ranges


def expected_lds01(sim):
    truth = sim.scan().ranges
    return np.where(np.isfinite(truth), np.round(truth * 1000) / 1000, 0.0)


def test_lds01_revolution_is_60_packets_that_decode_to_the_ray_cast_scan():
    sim = perfect_sim()
    stream = Lds01Stream(sim.scan_ranges)
    packets = stream.packets_until(0.2 - 1e-9)
    assert len(packets) == 60 and all(len(packet) == 42 for packet in packets)
    assert [packet[1] for packet in packets] == list(range(0xA0, 0xDC))
    assert all(struct.unpack_from("<H", packet, 2)[0] == 3000 for packet in packets)  # 300 rpm x 10
    assert all(lds01_checksum_ok(packet) for packet in packets)
    ranges = lds01_ranges(packets)
    assert np.array_equal(ranges, expected_lds01(sim))
    assert (ranges > 0).sum() > 200  # the world is all around


def test_lds01_e_stops_and_b_restarts_the_stream():
    stream = Lds01Stream(perfect_sim().scan_ranges)
    assert len(stream.packets_until(0.1 + 1e-9)) == 31  # packets at 0, 1/300, ... 30/300 s
    stream.command(b"e", 0.1)
    assert stream.packets_until(1.0) == []
    stream.command(b"b", 1.0)
    assert len(stream.packets_until(1.1 + 1e-9)) == 31


# --- LDS-02: 47-byte packets with CRC-8 -----------------------------------------------------

def crc8_poly_4d(data):
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x4D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def ld08_points(packet):
    """(range m, CCW angle deg) per point, as ROBOTIS's LD08 driver computes them; zero distances dropped."""
    speed, start = struct.unpack_from("<HH", packet, 2)
    end, = struct.unpack_from("<H", packet, 42)
    assert ((end // 100 - start // 100 + 360) % 360) <= speed * 12 / 2300 * 3 / 2  # the driver's sanity check
    step = ((end + 36000 - start) % 36000) / 11 / 100
    points = []
    for i in range(12):
        distance, _confidence = struct.unpack_from("<HB", packet, 6 + 3 * i)
        angle = (start / 100 + i * step) % 360 if i < 11 else (end % 36000) / 100
        if distance == 0:
            continue
        x, y = distance + 5.9, distance * 0.11923 - 20.14
        corrected = ((360 - angle) + math.atan(y / x) * 180 / 3.14159) % 360
        points.append((math.hypot(x, y) / 1000.0, corrected))
    return points


def test_lds02_packets_carry_crc8_and_correct_to_the_ray_cast_ranges():
    sim = perfect_sim()
    packets = Lds02Stream(sim.scan_ranges).packets_until(0.2 - 1e-9)
    assert len(packets) == 30 and all(len(packet) == 47 for packet in packets)
    assert all(packet[0] == 0x54 and packet[1] == 0x2C for packet in packets)
    assert all(crc8_poly_4d(packet[:46]) == packet[46] for packet in packets)
    points = [point for packet in packets for point in ld08_points(packet)]
    assert len(points) > 250
    ranges = np.array([r for r, _ in points])
    truth = sim.scan_ranges(np.radians([angle for _, angle in points]), 8.0)
    errors = np.abs(ranges - truth)
    # Points on an obstacle's silhouette may land beside it; everything else within rounding.
    assert np.mean(errors < 0.002) > 0.97


# --- over the pty, with pyserial ----------------------------------------------------------

@pytest.fixture(params=["LDS-01", "LDS-02"])
def lidar_robot(request, tmp_path):
    robot = RealTimeRobot(world="turtlebot3_world", model="burger", pose=POSE, seed=2, noise=NoiseConfig.none(),
                          lds_link=tmp_path / "ttyUSB0", lds_model=request.param).start()
    yield robot
    robot.stop()


def read_for(port, seconds):
    data, deadline = b"", time.monotonic() + seconds
    while time.monotonic() < deadline:
        data += port.read(4096)
    return data


def test_lidar_streams_a_scan_of_the_world_over_its_serial_port(lidar_robot):
    model = lidar_robot.devices["lds"].model
    with serial.Serial(str(lidar_robot.devices["lds"].link.path), 230400 if model == "LDS-01" else 115200,
                       timeout=0.05) as port:
        data = read_for(port, 0.6)
    with lidar_robot.lock:
        sim = lidar_robot.sim
        if model == "LDS-01":
            packets = split_lds01(data)
            assert len(packets) >= 60
            ranges = lds01_ranges(packets)
            assert np.array_equal(ranges, expected_lds01(sim))
        else:
            packets = [data[i:i + 47] for i in range(len(data) - 46)
                       if data[i] == 0x54 and data[i + 1] == 0x2C and crc8_poly_4d(data[i:i + 46]) == data[i + 46]]
            assert len(packets) >= 30
            points = [point for packet in packets for point in ld08_points(packet)]
            truth = sim.scan_ranges(np.radians([angle for _, angle in points]), 8.0)
            assert np.mean(np.abs(np.array([r for r, _ in points]) - truth) < 0.002) > 0.97


def test_lds01_stops_on_e_over_the_wire(tmp_path):
    robot = RealTimeRobot(world="turtlebot3_world", pose=POSE, lds_link=tmp_path / "lds").start()
    try:
        with serial.Serial(str(tmp_path / "lds"), 230400, timeout=0.05) as port:
            assert read_for(port, 0.3)
            port.write(b"e")
            wait_until(lambda: not robot.devices["lds"].status()["spinning"], 5, "LDS-01 ignored 'e'")
            read_for(port, 0.1)  # what was already on its way
            assert read_for(port, 0.4) == b""
            port.write(b"b")
            wait_until(lambda: port.read(4096), 5, "LDS-01 did not restart on 'b'")
    finally:
        robot.stop()


def test_lidar_faults_corrupt_packets_yet_good_ones_still_parse(lidar_robot):
    model = lidar_robot.devices["lds"].model
    assert lidar_robot.execute("faults lds garbage=0.3,checksum=0.3") == "ok"
    with serial.Serial(str(lidar_robot.devices["lds"].link.path), BAUD_RATES[model], timeout=0.05) as port:
        port.reset_input_buffer()
        data = read_for(port, 1.0)
    counts = lidar_robot.devices["lds"].status()["faults_injected"]
    assert counts["garbage"] > 0 and counts["checksum"] > 0
    if model == "LDS-01":
        packets = split_lds01(data)
        good = [packet for packet in packets if lds01_checksum_ok(packet)]
        assert len(good) < len(packets) and len(good) > 60
    else:
        starts = [i for i in range(len(data) - 46) if data[i] == 0x54 and data[i + 1] == 0x2C]
        good = [i for i in starts if crc8_poly_4d(data[i:i + 46]) == data[i + 46]]
        assert len(good) < len(starts) and len(good) > 30


def test_lidar_unplug_and_replug(lidar_robot):
    path = lidar_robot.devices["lds"].link.path
    port = serial.Serial(str(path), timeout=0.05)
    assert read_for(port, 0.2)
    assert lidar_robot.execute("unplug lds") == "ok"
    assert not path.exists()
    with pytest.raises(serial.SerialException):
        read_for(port, 0.5)
    port.close()
    assert lidar_robot.execute("replug lds") == "ok"
    with serial.Serial(str(path), timeout=0.05) as port:
        assert read_for(port, 0.3)
