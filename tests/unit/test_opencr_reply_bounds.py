"""The OpenCR link reads replies through ROBOTIS's dynamixel_sdk, with no buffer of ours: whatever the board (or
something posing as it) sends, one reply read holds at most the SDK's packet limit (issue #18: every parser
buffer bounded; docs/security.md#limits)."""
import inspect

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

# The unit tests need no more than numpy, scipy, PyYAML and the test tools (docs/developing.md); the SDK is in .venv.
dynamixel_sdk = pytest.importorskip("dynamixel_sdk")
protocol2_packet_handler = pytest.importorskip("dynamixel_sdk.protocol2_packet_handler")
LIMIT = protocol2_packet_handler.RXPACKET_MAX_LEN + 7  # its length field's bound plus the header before it


class StreamPort:
    """A port that yields `data` as asked, then times out; it notes the largest read asked for."""

    def __init__(self, data):
        self.data = bytearray(data)
        self.is_using = True
        self.largest_request = 0

    def readPort(self, length):  # the SDK's name
        self.largest_request = max(self.largest_request, length)
        chunk = list(self.data[:length])
        del self.data[:length]
        return chunk

    def isPacketTimeout(self):  # the SDK's name
        return not self.data


def status_header(length):
    """The start of a Protocol 2.0 status packet from ID 200 announcing `length` bytes to follow."""
    return bytes([0xFF, 0xFF, 0xFD, 0x00, 200, length & 0xFF, length >> 8, 0x55])


PIECES = st.one_of(st.binary(max_size=300), st.integers(min_value=0, max_value=0xFFFF).map(status_header))


@settings(max_examples=300, deadline=None)
@given(st.lists(PIECES, max_size=30))
def test_a_reply_read_holds_at_most_one_packet_whatever_arrives(pieces):
    port = StreamPort(b"".join(pieces))
    handler = dynamixel_sdk.PacketHandler(2.0)
    # PyPI's 4.x added fast_option (False: an ordinary reply); ROS noetic's 3.7 has no such argument.
    fast = (False,) if "fast_option" in inspect.signature(handler.rxPacket).parameters else ()
    packet, result = handler.rxPacket(port, *fast)
    assert port.largest_request <= LIMIT and len(packet) <= LIMIT
    assert result in (dynamixel_sdk.COMM_SUCCESS, dynamixel_sdk.COMM_RX_CORRUPT, dynamixel_sdk.COMM_RX_TIMEOUT)
