"""The LIDAR's serial stream: bytes through, motor command on open, survives unplug/replug, quiet after close."""
from testkit.recording_log import RecordingLog
from testkit.ros_harness import wait_until
from turtlebot3c_bringup.serial_stream import SerialStream
from turtlebot3c_common.backoff import Backoff
from turtlebot3c_sim.pty_link import PtyLink


def read_until(stream, expected, timeout=5):
    received = bytearray()

    def got_it():
        received.extend(stream.read())
        return expected in received
    wait_until(got_it, timeout, lambda: f"never read {expected!r}; got {bytes(received)!r}")


def test_stream_reopens_an_unplugged_device_and_reports_it_once(tmp_path):
    device = PtyLink(tmp_path / "ttyUSB0")
    device.plug()
    log = RecordingLog()
    stream = SerialStream(str(device.path), 230400, on_open=b"b", on_close=b"e", log=log, backoff=Backoff(0.05, 0.2))
    try:
        stream.read()  # opens the port
        wait_until(lambda: device.read(0.05) == b"b", 5, "the motor start command never arrived")
        device.write(b"\xfa\xa0hello")
        read_until(stream, b"hello")
        device.unplug()
        wait_until(lambda: stream.read() == b"" and not stream.is_open, 5, "the unplug went unnoticed")
        assert stream.losses == 1
        assert [level for level, _ in log.lines].count("error") == 1
        device.plug()
        wait_until(lambda: stream.read() == b"" and stream.is_open, 5, "never reopened")
        device.write(b"again")
        read_until(stream, b"again")
        assert stream.reconnections == 1
        assert any("reopened" in message for _, message in log.lines)
        device.read(0.05)  # the motor start of the reopening
        stream.close()
        wait_until(lambda: device.read(0.05) == b"e", 5, "the motor stop command never arrived")
    finally:
        stream.close()
        device.close()
    errors = len(log.lines)
    assert stream.read() == b"" and len(log.lines) == errors  # closed for good: silent


def test_a_missing_device_is_retried_quietly(tmp_path):
    log = RecordingLog()
    stream = SerialStream(str(tmp_path / "nothing"), 115200, log=log, backoff=Backoff(0.01, 0.05))
    for _ in range(20):
        assert stream.read() == b""
    assert not stream.is_open
    assert len(log.lines) == 1 and "no LIDAR at" in log.lines[0][1] and "lds-port=" in log.lines[0][1]
    assert stream.problem.fix.startswith("plug the LIDAR in")
