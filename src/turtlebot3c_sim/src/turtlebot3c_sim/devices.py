"""The fake OpenCR and the fake LIDAR served on pseudo-terminals, each in a thread of its own.

A device thread owns its `PtyLink`: plugging, unplugging, reading and writing
all happen in that thread; `unplug()` and `replug()` from elsewhere only ask
for the change and wait until it is done. Faults are drawn per reply (OpenCR)
or per packet (LIDAR), see `faults`.
"""
import threading
import time
from typing import List, Tuple

from . import dynamixel_protocol as dxl
from . import fake_rosserial
from .fake_lds import BAUD_RATES, make_stream
from .faults import LIDAR_FAULTS, OPENCR_FAULTS, FaultInjector
from .pty_link import PtyLink

POLL_INTERVAL = 0.002  # s between looks at the link when the host is quiet


class DeviceThread(threading.Thread):
    kind = "device"

    def __init__(self, link_path, robot, faults: FaultInjector):
        super().__init__(name=f"fake-{self.kind}", daemon=True)
        self.link = PtyLink(link_path)
        self.robot = robot
        self.faults = faults
        self.bytes_in = 0
        self.bytes_out = 0
        self.plug_count = 0
        self.unplugged_at = None  # simulated time of the last unplug: when the fault happened
        self._want_plugged = True
        self._applied = threading.Condition()
        self._stopping = threading.Event()
        self.error = None

    # --- requests from other threads ----------------------------------------------

    def unplug(self, timeout: float = 5.0):
        self._request(False, timeout)

    def replug(self, timeout: float = 5.0):
        self._request(True, timeout)

    def _request(self, plugged: bool, timeout: float):
        with self._applied:
            self._want_plugged = plugged
            if not self._applied.wait_for(lambda: self.link.plugged == plugged or not self.is_alive(), timeout):
                raise TimeoutError(f"{self.kind} did not become {'plugged' if plugged else 'unplugged'}")

    def stop(self, timeout: float = 5.0):
        self._stopping.set()
        self.join(timeout)

    def wait_plugged(self, timeout: float = 5.0) -> bool:
        with self._applied:
            return self._applied.wait_for(lambda: self.link.plugged, timeout)

    # --- the device's own thread ---------------------------------------------------

    def run(self):
        try:
            while not self._stopping.is_set():
                self._apply_plug_state()
                if self.link.plugged:
                    self.serve()
                else:
                    self._stopping.wait(POLL_INTERVAL)
        except Exception as error:  # reported by the robot's status; the device is then unplugged
            self.error = repr(error)
            raise
        finally:
            self.link.close()
            with self._applied:
                self._applied.notify_all()

    def _apply_plug_state(self):
        if self._want_plugged == self.link.plugged:
            return
        with self._applied:
            if self._want_plugged:
                self.link.plug()
                self.plug_count += 1
                self.powered_on()
            else:
                self.link.unplug()
                self.unplugged_at = self.robot.sim.time
            self._applied.notify_all()

    def send(self, data: bytes):
        self.bytes_out += self.link.write(data)

    def powered_on(self):
        """Called after each plug: the device starts from its power-on state."""

    def serve(self):
        raise NotImplementedError

    def status(self) -> dict:
        return {"plugged": self.link.plugged, "path": str(self.link.path), "device": self.link.slave_name,
                "plugs": self.plug_count, "unplugged_at": self.unplugged_at,
                "bytes_in": self.bytes_in, "bytes_out": self.bytes_out,
                "dropped_bytes": self.link.dropped_bytes, "faults": self.faults.describe(),
                "faults_injected": dict(self.faults.counts), "error": self.error}


OPENCR_FIRMWARES = ("dynamixel", "rosserial")


class OpenCRDevice(DeviceThread):
    """Answers Dynamixel 2.0 instructions with `robot.board` on the link.

    With `firmware="rosserial"` the board runs ROBOTIS's ROS 1 firmware instead
    (`fake_rosserial`): it ignores Dynamixel packets and talks rosserial, and only
    while the host's port is set to 115200 baud, as that firmware is (the real board's
    USB link would carry any rate: this makes the tests prove the driver asks at 115200).
    """

    kind = "opencr"

    def __init__(self, link_path, robot, faults: FaultInjector = None, firmware: str = "dynamixel"):
        super().__init__(link_path, robot, faults or FaultInjector(OPENCR_FAULTS))
        self._parser = dxl.PacketParser()
        self._delayed: List[Tuple[float, bytes]] = []
        self.replies = 0
        self.firmware = self._checked(firmware)
        self._rosserial = fake_rosserial.RosserialFirmware()

    @staticmethod
    def _checked(firmware):
        if firmware not in OPENCR_FIRMWARES:
            raise ValueError(f"unknown OpenCR firmware {firmware!r}; known: {', '.join(OPENCR_FIRMWARES)}")
        return firmware

    def flash(self, firmware: str):
        """Run another firmware from now on (the board restarts: nothing half-received survives)."""
        self.firmware = self._checked(firmware)
        self.powered_on()

    def powered_on(self):
        self._parser = dxl.PacketParser()  # USB replug: whatever was half-received is gone
        self._delayed = []
        self._rosserial = fake_rosserial.RosserialFirmware()

    def serve(self):
        data = self.link.read(POLL_INTERVAL)
        if self.firmware == "rosserial":
            self._serve_rosserial(data)
            return
        self._send_due_delayed()
        if not data:
            return
        self.bytes_in += len(data)
        for packet in self._parser.feed(data):
            with self.robot.lock:
                reply = self.robot.board.handle(packet)
            if reply is not None:
                self._reply(reply)

    def _serve_rosserial(self, data: bytes):
        self.bytes_in += len(data)
        if self.link.host_baud() != fake_rosserial.BAUD:
            return  # at another rate, neither side makes sense of the other's bytes
        now = time.monotonic()
        reply = self._rosserial.receive(data, now) + self._rosserial.due(now)
        if reply:
            self.send(reply)

    def _reply(self, reply: bytes):
        faults = self.faults
        if faults.happens("drop"):
            return
        if faults.happens("crc"):
            reply = reply[:-1] + bytes([reply[-1] ^ 0xA5])
        if faults.happens("truncate"):
            reply = faults.cut(reply)
        if faults.happens("garbage"):
            reply = faults.garbage() + reply
        if faults.happens("delay"):
            self._delayed.append((time.monotonic() + faults.option("delay_time"), reply))
            return
        self.replies += 1
        self.send(reply)

    def _send_due_delayed(self):
        now = time.monotonic()
        while self._delayed and self._delayed[0][0] <= now:
            self.send(self._delayed.pop(0)[1])
            self.replies += 1

    def status(self) -> dict:
        status = super().status()
        board = self.robot.board
        status.update(firmware=self.firmware, rosserial_requests=self._rosserial.requests,
                      replies=self.replies, crc_errors_received=self._parser.crc_errors,
                      requests=board.requests, heartbeat_stalls=board.heartbeat_stalls, stalled_at=board.stalled_at,
                      torque=board.torque_enabled, goal_velocity=list(board.goal_velocity),
                      sounds=list(board.sounds), calibrations=board.calibrations)
        return status


class LidarDevice(DeviceThread):
    """Streams LDS-01 or LDS-02 packets ray-cast in `robot.sim` on the link.

    The LIDARs sit behind a USB-serial bridge, so the rate matters: while the host's port is
    set to another baud rate than the model's, what it reads is noise (each byte scrambled), and
    what it writes (the LDS-01's start and stop) does not reach the LIDAR.
    """

    kind = "lds"

    def __init__(self, link_path, robot, model: str, faults: FaultInjector = None):
        super().__init__(link_path, robot, faults or FaultInjector(LIDAR_FAULTS))
        self.model = model
        self.stream = make_stream(model, robot.sim.scan_ranges, robot.sim.time)
        self.packets = 0

    def powered_on(self):
        with self.robot.lock:
            self.stream = make_stream(self.model, self.robot.sim.scan_ranges, self.robot.sim.time)

    def swap(self, model: str):
        """Another LIDAR model on the same port (the owner fitted the other one), started afresh."""
        make_stream(model, self.robot.sim.scan_ranges, 0.0)  # ValueError for an unknown model
        self.model = model
        self.powered_on()

    def serve(self):
        data = self.link.read(POLL_INTERVAL)
        host_baud = self.link.host_baud()
        rate_matches = host_baud is None or host_baud == BAUD_RATES[self.model]
        with self.robot.lock:
            now = self.robot.sim.time
            if data:
                self.bytes_in += len(data)
                if rate_matches:
                    self.stream.command(data, now)
            packets = self.stream.packets_until(now)
        for packet in packets:
            self._emit(packet if rate_matches else _misread(packet))

    def _emit(self, packet: bytes):
        faults = self.faults
        if faults.happens("drop"):
            return
        if faults.happens("checksum"):
            packet = packet[:-1] + bytes([packet[-1] ^ 0x5A])
        if faults.happens("truncate"):
            packet = faults.cut(packet)
        if faults.happens("garbage"):
            packet = faults.garbage() + packet
        self.packets += 1
        self.send(packet)

    def status(self) -> dict:
        status = super().status()
        status.update(model=self.model, packets=self.packets, spinning=self.stream.spinning)
        return status


def _misread(data: bytes) -> bytes:
    """Bytes as a UART at the wrong rate reads them: nothing of the packets' structure survives."""
    return bytes((byte * 73 + 41) & 0xFF for byte in data)[::2]
