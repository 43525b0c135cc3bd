"""LDS-01 and LDS-02 byte streams: scans as the upstream drivers lay them out, resync on bad bytes, no crash."""
import math
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from turtlebot3c_bringup import lds01_protocol, lds02_protocol
from turtlebot3c_bringup.laser_scan import fill_scan
from turtlebot3c_bringup.lds_models import Lds01, Lds02, make_lds

# --- LDS-01 --------------------------------------------------------------------------------

def lds01_revolution(range_of_reading=lambda index: 1000 + index, speed=3000):
    """Bytes of one revolution; reading number n (in the LIDAR's clockwise order) gets range_of_reading(n) mm."""
    return b"".join(
        lds01_protocol.encode_packet(packet, speed, [(100 + k, range_of_reading(6 * packet + k)) for k in range(6)])
        for packet in range(60))


def feed_in_chunks(parser, data, chunk=97):
    out = []
    for start in range(0, len(data), chunk):
        out += parser.feed(data[start:start + chunk])
    return out


def test_lds01_beams_are_counter_clockwise_like_the_robotis_driver():
    parser = lds01_protocol.Lds01Parser()
    revolutions = feed_in_chunks(parser, lds01_revolution() * 2 + lds01_revolution()[:2])
    assert len(revolutions) == 2
    first = revolutions[0]
    # reading n lands on beam 359 - n
    assert first.ranges[359] == 1.000 and first.ranges[0] == 1.359 and first.ranges[300] == 1.059
    assert first.intensities[359] == 100.0
    assert first.rpm == 300.0 and first.packets == 60
    assert parser.bytes_discarded == 0


def test_lds01_garbage_between_packets_costs_only_the_packet_before_it():
    # Without a checksum, garbage after packet 9 looks like a byte inserted into packet 9: both go.
    clean = lds01_revolution()
    noisy = clean[:420] + b"\xfa\xa7garbage\xfa" + clean[420:] + lds01_revolution()[:2]
    parser = lds01_protocol.Lds01Parser()
    [revolution] = feed_in_chunks(parser, noisy)
    assert revolution.packets == 59
    assert revolution.ranges[359 - 54] == 0.0 and revolution.ranges[359 - 60] == 1.060
    assert parser.bytes_discarded == 42 + len(b"\xfa\xa7garbage\xfa")


def test_lds01_packet_with_an_inserted_byte_is_dropped_not_published_shifted():
    clean = lds01_revolution()
    broken = clean[:42 * 10 + 20] + b"\x55" + clean[42 * 10 + 20:] + lds01_revolution()[:2]
    [revolution] = feed_in_chunks(lds01_protocol.Lds01Parser(), broken)
    assert revolution.packets == 59
    assert all(revolution.ranges[359 - (60 + k)] == 0.0 for k in range(6))  # packet 10 lost: no return
    assert revolution.ranges[359 - 66] == 1.066


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=3000), st.integers(min_value=1, max_value=200))
def test_lds01_parser_survives_any_bytes(garbage, chunk):
    parser = lds01_protocol.Lds01Parser()
    for revolution in feed_in_chunks(parser, garbage, chunk):
        assert len(revolution.ranges) == 360
    # and it still finds the real packets after the garbage
    revolutions = feed_in_chunks(parser, lds01_revolution() * 2 + lds01_revolution()[:2], chunk)
    assert revolutions[-1].packets == 60 and revolutions[-1].ranges[359] == 1.0


# --- LDS-02 --------------------------------------------------------------------------------

def lds02_stream(revolutions=2, distance=lambda angle: 1500, speed=3600):
    """Packets covering nearly `revolutions` turns at 2300 points/s; points in the sensor's clockwise angles."""
    step = speed / 2300.0
    packets, angle = [], 0.0
    while angle + 12 * step < 360.0 * revolutions:  # the last turn stays open: only revolutions - 1 complete
        start = angle % 360.0
        points = [(distance((start + i * step) % 360.0), 200) for i in range(12)]
        end = (start + 11 * step) % 360.0
        packets.append(lds02_protocol.encode_packet(speed, int(start * 100), int(end * 100), points))
        angle += 12 * step
    return b"".join(packets)


def test_lds02_crc8_uses_polynomial_0x4d():
    assert lds02_protocol.CRC_TABLE[1] == 0x4D
    assert lds02_protocol.crc8(b"") == 0


def test_lds02_revolutions_end_where_the_angle_wraps():
    parser = lds02_protocol.Lds02Parser()
    revolutions = feed_in_chunks(parser, lds02_stream(3))
    assert len(revolutions) == 2
    assert all(0 <= point.angle < 360 for revolution in revolutions for point in revolution)
    assert revolutions[0][0].angle < 2 and revolutions[0][-1].angle > 355
    assert parser.crc_errors == 0 and parser.bytes_discarded == 0


def test_lds02_fixed_scan_has_360_counter_clockwise_beams():
    # an obstacle at 0.8 m from 80 to 100 degrees clockwise (the robot's right), 2 m elsewhere
    def distance(angle):
        return 800 if 80 <= angle <= 100 else 2000
    [points, _] = feed_in_chunks(lds02_protocol.Lds02Parser(), lds02_stream(3, distance))[:2]
    ranges, intensities = lds02_protocol.fixed_scan(points, correct_geometry=False)
    assert len(ranges) == 360
    # 90 degrees clockwise is 270 counter-clockwise; at 2300 points/s and 10 turns/s not every beam has a point
    near_obstacle = [ranges[beam] for beam in range(262, 279) if ranges[beam] > 0]
    opposite = [ranges[beam] for beam in range(82, 99) if ranges[beam] > 0]
    assert len(near_obstacle) >= 8 and set(near_obstacle) == {0.8}
    assert len(opposite) >= 8 and set(opposite) == {2.0}
    assert len(points) - 2 <= sum(1 for value in ranges if value > 0) <= len(points)  # rare shared beams
    assert max(intensities) == 200.0


def test_lds02_geometry_correction_turns_and_lengthens_readings_like_the_ld08_optics():
    point = lds02_protocol.Point(angle=10.0, distance=1000, confidence=200)
    distance, angle = lds02_protocol.corrected(point)
    assert distance == math.hypot(1005.9, 1000 * 0.11923 - 20.14)
    assert angle == (350.0 + math.degrees(math.atan((1000 * 0.11923 - 20.14) / 1005.9)))


def test_lds02_bad_crc_packet_is_dropped_and_counted():
    stream = bytearray(lds02_stream(3))
    stream[47 * 5 + 10] ^= 0xFF
    parser = lds02_protocol.Lds02Parser()
    revolutions = feed_in_chunks(parser, bytes(stream))
    assert parser.crc_errors >= 1
    assert len(revolutions) == 2
    assert sum(len(r) for r in revolutions) == parser.packets_accepted * 12 - len(parser._points)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=3000), st.integers(min_value=1, max_value=200))
def test_lds02_parser_survives_any_bytes(garbage, chunk):
    parser = lds02_protocol.Lds02Parser()
    for points in feed_in_chunks(parser, garbage, chunk):
        ranges, _ = lds02_protocol.fixed_scan(points)
        assert len(ranges) == 360
    assert len(feed_in_chunks(parser, lds02_stream(3), chunk)) >= 2


def test_lds02_packets_whose_angle_never_wraps_are_dropped_in_bounded_memory_and_counted():
    # Issue #18 item 5: CRC-valid packets of a stalled motor (speed 0, one fixed angle) never end a revolution.
    stuck = lds02_protocol.encode_packet(0, 9000, 9000, [(1000, 200)] * 12)
    lds = Lds02()
    scans = feed_in_chunks(lds, stuck * 2000, 470)
    assert not scans and lds.parser.packets_accepted == 2000
    assert len(lds.parser.current_points) <= lds02_protocol.MAX_REVOLUTION_POINTS
    assert lds.counters()["overlong revolutions dropped"] == 2000 * 12 // lds02_protocol.MAX_REVOLUTION_POINTS
    assert len(feed_in_chunks(lds, lds02_stream(3))) >= 2  # a turning LIDAR is read again at once


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.binary(max_size=200), st.sampled_from(["lds01", "lds02", "stuck"])), max_size=40),
       st.integers(min_value=1, max_value=500))
def test_both_parsers_hold_at_most_a_packet_of_bytes_and_a_revolution_of_points(pieces, chunk):
    stuck = lds02_protocol.encode_packet(0, 100, 100, [(500, 10)] * 12) * 50
    known = {"lds01": lds01_revolution(), "lds02": lds02_stream(1), "stuck": stuck}
    data = b"".join(known.get(piece, piece) for piece in pieces)
    lds01, lds02 = lds01_protocol.Lds01Parser(), lds02_protocol.Lds02Parser()
    for start in range(0, len(data), chunk):
        lds01.feed(data[start:start + chunk])
        lds02.feed(data[start:start + chunk])
        assert lds01.buffered <= lds01_protocol.PACKET_SIZE + 1 and len(lds01._packets) <= 60
        assert lds02.buffered < lds02_protocol.PACKET_SIZE
        assert len(lds02.current_points) <= lds02_protocol.MAX_REVOLUTION_POINTS


@settings(max_examples=100, deadline=None)
@given(st.integers(min_value=0, max_value=2**32 - 1))
def test_both_lidars_survive_a_real_stream_with_random_bytes_sprinkled_in(seed):
    rng = random.Random(seed)
    for lds, clean in ((Lds01(), lds01_revolution() * 4), (Lds02(), lds02_stream(4))):
        noisy = bytearray(clean)
        for _ in range(rng.randint(0, 30)):
            noisy.insert(rng.randrange(len(noisy)), rng.randrange(256))
        scans = feed_in_chunks(lds, bytes(noisy), rng.randint(1, 300))
        assert all(len(scan.ranges) == 360 for scan in scans)
        assert scans, f"{lds.name}: no scan at all from a mostly clean stream"


# --- the LaserScan layout ---------------------------------------------------------------------

class _Header:
    stamp = frame_id = None


class _Message:
    def __init__(self):
        self.header = _Header()


def test_laser_scan_geometry_is_the_upstream_one():
    scan = fill_scan(_Message(), [1.0] * 360, [0.0] * 360, stamp=12.5, frame_id="base_scan",
                     range_min=0.12, range_max=3.5, time_increment=-0.2 / 360, scan_time=0.2)
    assert scan.header.frame_id == "base_scan" and scan.header.stamp == 12.5
    assert scan.angle_min == 0.0
    assert scan.angle_increment == 2 * math.pi / 360
    assert scan.angle_max == 2 * math.pi - scan.angle_increment
    assert (scan.range_min, scan.range_max) == (0.12, 3.5)
    assert scan.time_increment == -0.2 / 360
    assert scan.scan_time == 0.2


# --- scan timing: beam i measured at stamp + i * time_increment -------------------------------

def test_lds01_scan_is_stamped_when_beam_0_was_measured_and_counts_time_backwards():
    # Beam 0 is the last reading of packet 59; the revolution is known complete when the next
    # packet's header arrives, one packet (1/300 s at 300 rpm) later.
    data = lds01_revolution() + lds01_revolution()[:2]
    [scan] = Lds01().feed(data, read_time=100.0)
    assert scan.scan_time == pytest.approx(0.2)
    assert scan.time_increment == pytest.approx(-0.2 / 360)
    assert scan.stamp == pytest.approx(100.0 - 0.2 / 60)
    # beam 359 (the first reading of packet 0) comes out 359 beams before beam 0, at the revolution's start
    assert scan.stamp + 359 * scan.time_increment == pytest.approx(100.0 - 0.2 / 60 - 0.2, abs=0.2 / 60)


def test_lds01_scan_read_from_a_backlog_is_stamped_when_its_bytes_came_not_when_they_were_read():
    # Two revolutions read at once: the first ended a whole revolution (2520 bytes at 12600 B/s) earlier.
    data = lds01_revolution() * 2 + lds01_revolution()[:2]
    first, second = Lds01().feed(data, read_time=50.0)
    assert second.stamp - first.stamp == pytest.approx(0.2, abs=0.005)
    assert second.stamp == pytest.approx(50.0 - 0.2 / 60)


def test_lds02_scan_is_stamped_at_the_end_of_its_revolution_and_counts_time_backwards():
    # 3600 deg/s: 10 revolutions a second; the stream's last revolution stays open.
    [scan] = Lds02().feed(lds02_stream(2), read_time=20.0)
    assert scan.scan_time == pytest.approx(0.1)
    assert scan.time_increment == pytest.approx(-0.1 / 360)
    # read at 20.0 with a few packets of the open revolution after it: the stamp is earlier by their time
    assert 20.0 - 0.1 < scan.stamp < 20.0


def test_lds02_revolution_joined_midway_is_not_published():
    # The driver opened the port with the LIDAR three quarters round: that first stretch is no scan.
    stream = lds02_stream(3)
    packet_count = len(stream) // 47
    lds = Lds02()
    scans = lds.feed(stream[47 * (packet_count * 7 // 24):])  # 7/8 of a turn in: 1/8 of a turn before the wrap
    assert len(scans) == 1 and sum(1 for value in scans[0].ranges if value > 0) > 200
    assert lds.counters()["revolutions dropped"] == 1


def test_lds02_points_measured_after_the_wrap_that_land_on_the_front_go_to_the_scan_that_ends_there():
    # Each revolution sees everything at its own distance, so a beam tells which revolution measured it.
    # The optics' offset moves a 2 m point 6 degrees counter-clockwise: the first points of a revolution
    # land on beams 0-6, which a scan measures last (time_increment < 0): they belong to the scan before.
    def distance_mm(revolution):
        return 2000 + 500 * revolution

    packets = []
    for number in range(3 * 30 + 2):  # three revolutions of 30 packets, and the next one under way
        revolution, first = divmod(number, 30)
        points = [(distance_mm(revolution), 200)] * 12
        packets.append(lds02_protocol.encode_packet(1800, first * 1200, (first * 12 + 11) * 100, points))
    scans = Lds02().feed(b"".join(packets))
    assert len(scans) == 3

    def metres(distance):
        return lds02_protocol.corrected(lds02_protocol.Point(0.0, distance, 200))[0] / 1000.0
    for number, scan in enumerate(scans):
        assert all(scan.ranges[beam] == metres(distance_mm(number + 1)) for beam in range(0, 6))
        assert all(scan.ranges[beam] == metres(distance_mm(number)) for beam in range(10, 350))


def test_unknown_motor_speed_gives_no_beam_timing():
    packets = [lds01_protocol.encode_packet(index, 0, [(100, 1000)] * 6) for index in range(60)]
    [scan] = Lds01().feed(b"".join(packets) + packets[0][:2], read_time=7.0)
    assert (scan.time_increment, scan.scan_time, scan.stamp) == (0.0, 0.0, 7.0)


def test_unknown_lidar_model_names_the_known_ones():
    try:
        make_lds("LDS-03")
    except ValueError as error:
        assert "LDS-01, LDS-02" in str(error)
    else:
        raise AssertionError("LDS-03 was accepted")
