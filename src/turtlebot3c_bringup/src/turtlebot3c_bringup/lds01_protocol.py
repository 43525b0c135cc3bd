"""The LDS-01 (HLS-LFCD2) byte stream: 42-byte packets, 60 per revolution, 6 readings each.

Packet: 0xFA, 0xA0 + index (0..59, 6 degrees each), speed (uint16 LE, rpm x 10),
six readings of {intensity uint16 LE, range mm uint16 LE, 2 reserved bytes},
2 checksum bytes. ROBOTIS's driver does not check the checksum and no
ROBOTIS source defines it, so this parser does not either; instead it only
trusts a packet whose framing is confirmed by the header of the next index
right after it (the LIDAR streams packets back to back). Random bytes then
almost never pass for a packet, and a bad byte costs at most the packet it
lands in and the one before it. Beams of packets that never
arrived are 0, the driver's "no return".
"""
import struct
from typing import List, NamedTuple, Optional

HEADER = 0xFA
INDEX_BASE = 0xA0
PACKET_SIZE = 42
PACKETS_PER_REVOLUTION = 60
READINGS_PER_PACKET = 6
BEAMS = PACKETS_PER_REVOLUTION * READINGS_PER_PACKET  # 360, one per degree

START_MOTOR = b"b"
STOP_MOTOR = b"e"


class Revolution(NamedTuple):
    ranges: List[float]  # m, beam i at i degrees counter-clockwise
    intensities: List[float]
    rpm: float  # mean motor speed over the revolution's packets, 0 if unknown
    packets: int  # how many of the 60 packets arrived


class _Packet(NamedTuple):
    index: int
    speed_rpm_x10: int
    readings: tuple  # (intensity, range_mm) x 6


def packet_index(data, offset) -> Optional[int]:
    if data[offset] != HEADER:
        return None
    index = data[offset + 1] - INDEX_BASE
    return index if 0 <= index < PACKETS_PER_REVOLUTION else None


def decode_packet(data, offset) -> _Packet:
    speed, = struct.unpack_from("<H", data, offset + 2)
    readings = tuple(struct.unpack_from("<HH", data, offset + 4 + 6 * k) for k in range(READINGS_PER_PACKET))
    return _Packet(data[offset + 1] - INDEX_BASE, speed, readings)


def encode_packet(index: int, speed_rpm_x10: int, readings) -> bytes:
    """A packet as the LIDAR sends it (for tests and tools); checksum bytes are left zero."""
    body = bytes((HEADER, INDEX_BASE + index)) + struct.pack("<H", speed_rpm_x10)
    for intensity, range_mm in readings:
        body += struct.pack("<HHH", intensity, range_mm, 0)
    return body + b"\0\0"


class Lds01Parser:
    """Feed it bytes as they come; it returns the revolutions completed by them. Never raises on data,
    and holds at most one packet and two bytes, and one revolution's packets, between feeds."""

    def __init__(self):
        self._buffer = bytearray()
        self._packets = {}
        self.bytes_discarded = 0
        self.packets_accepted = 0
        self.revolutions_incomplete = 0

    def feed(self, data: bytes) -> List[Revolution]:
        self._buffer.extend(data)
        revolutions = []
        buffer = self._buffer
        position = 0
        while len(buffer) - position >= PACKET_SIZE:
            index = packet_index(buffer, position)
            verdict = None if index is None else self._framing_confirmed(buffer, position, index)
            if verdict is None and index is not None:
                break  # a candidate packet: wait for the next header to confirm it
            if not verdict:
                position += 1
                self.bytes_discarded += 1
                continue
            revolution = self._accept(decode_packet(buffer, position))
            if revolution is not None:
                revolutions.append(revolution)
            position += PACKET_SIZE
        del buffer[:position]
        return revolutions

    @property
    def buffered(self) -> int:
        """Bytes held for the next feed: at most a packet and the two bytes that confirm it."""
        return len(self._buffer)

    @staticmethod
    def _framing_confirmed(buffer, position, index) -> Optional[bool]:
        """True if the packet at `position` is followed by the next index's header, False if not,
        None if the bytes that would tell have not arrived yet. (A byte lost or inserted inside a
        packet moves the next header, so this also rejects packets with shifted readings.)"""
        following = position + PACKET_SIZE
        if len(buffer) - following < 2:
            return None
        return packet_index(buffer, following) == (index + 1) % PACKETS_PER_REVOLUTION

    def _accept(self, packet: _Packet) -> Optional[Revolution]:
        revolution = None
        if self._packets and packet.index <= max(self._packets):
            revolution = self._finish()  # the previous revolution ended early: some packets were lost
        self._packets[packet.index] = packet
        self.packets_accepted += 1
        if packet.index == PACKETS_PER_REVOLUTION - 1:
            revolution = self._finish()
        return revolution

    def _finish(self) -> Revolution:
        ranges = [0.0] * BEAMS
        intensities = [0.0] * BEAMS
        for packet in self._packets.values():
            for k, (intensity, range_mm) in enumerate(packet.readings):
                beam = BEAMS - 1 - (READINGS_PER_PACKET * packet.index + k)  # the LIDAR turns clockwise
                ranges[beam] = range_mm / 1000.0
                intensities[beam] = float(intensity)
        speeds = [packet.speed_rpm_x10 for packet in self._packets.values()]
        count = len(self._packets)
        if count < PACKETS_PER_REVOLUTION:
            self.revolutions_incomplete += 1
        self._packets = {}
        return Revolution(ranges, intensities, sum(speeds) / len(speeds) / 10.0, count)
