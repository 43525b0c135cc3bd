"""Device side of Dynamixel Protocol 2.0: split a byte stream into instruction packets, build status packets.

The host side of the project talks through dynamixel_sdk; this is the other
end of the wire, for the fake OpenCR board. Packet layout:
`FF FF FD 00 | ID | LEN_L LEN_H | INST | params | CRC_L CRC_H`, LEN = params + 3,
CRC-16 (polynomial 0x8005, initial value 0, MSB first) over everything before
it; any `FF FF FD` inside the body is sent as `FF FF FD FD`.
"""
import struct
from typing import List, NamedTuple, Optional

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE

PING = 0x01
READ = 0x02
WRITE = 0x03
REBOOT = 0x08
STATUS = 0x55
SYNC_READ = 0x82
SYNC_WRITE = 0x83

# Error byte of a status packet.
ERROR_NONE = 0
ERROR_RESULT_FAIL = 1
ERROR_INSTRUCTION = 2
ERROR_CRC = 3
ERROR_DATA_RANGE = 4
ERROR_DATA_LENGTH = 5
ERROR_DATA_LIMIT = 6
ERROR_ACCESS = 7

MAX_PACKET_LENGTH = 1024  # longest LEN field accepted; anything longer is noise


def _crc_table():
    table = []
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return table


_CRC_TABLE = _crc_table()


def crc16(data: bytes, crc: int = 0) -> int:
    for byte in data:
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Insert the extra FD after every FF FF FD."""
    return body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def packet(device_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete packet (instruction or status) with stuffing and CRC."""
    body = stuff(bytes([instruction]) + bytes(params))
    head = HEADER + bytes([device_id]) + struct.pack("<H", len(body) + 2)
    without_crc = head + body
    return without_crc + struct.pack("<H", crc16(without_crc))


def status_packet(device_id: int, error: int = ERROR_NONE, params: bytes = b"") -> bytes:
    return packet(device_id, STATUS, bytes([error]) + bytes(params))


class Packet(NamedTuple):
    device_id: int
    instruction: int
    params: bytes  # unstuffed


class PacketParser:
    """Accumulates bytes and yields the valid packets in them; skips noise and packets with bad CRCs."""

    def __init__(self):
        self._buffer = bytearray()
        self.crc_errors = 0
        self.discarded_bytes = 0

    def feed(self, data: bytes) -> List[Packet]:
        self._buffer.extend(data)
        packets = []
        while True:
            found = self._next_packet()
            if found is None:
                return packets
            packets.append(found)

    def _next_packet(self) -> Optional[Packet]:
        while True:
            start = self._buffer.find(HEADER)
            if start < 0:
                # Keep a possible partial header at the end.
                keep = next((n for n in (3, 2, 1) if self._buffer.endswith(HEADER[:n])), 0)
                self._discard(len(self._buffer) - keep)
                return None
            self._discard(start)
            if len(self._buffer) < 7:
                return None
            length = struct.unpack_from("<H", self._buffer, 5)[0]
            if length < 3 or length > MAX_PACKET_LENGTH:
                self._discard(1)
                continue
            total = 7 + length
            if len(self._buffer) < total:
                return None
            raw = bytes(self._buffer[:total])
            if crc16(raw[:-2]) != struct.unpack_from("<H", raw, total - 2)[0]:
                self.crc_errors += 1
                self._discard(1)
                continue
            self._discard(total)
            self.discarded_bytes -= total  # a good packet is not noise
            body = unstuff(raw[7:-2])
            return Packet(raw[4], body[0], body[1:])

    def _discard(self, count):
        if count > 0:
            del self._buffer[:count]
            self.discarded_bytes += count
