"""A serial byte stream that survives unplugging: read what comes, reopen the device when it goes away."""
import time

import serial

from turtlebot3c_bringup.serial_errors import DEVICE_ERRORS, SerialProblem, explain_open_error
from turtlebot3c_common.backoff import Backoff


class SerialStream:
    def __init__(self, port: str, baud: int, on_open: bytes = b"", on_close: bytes = b"", log=None,
                 clock=None, backoff=None, device: str = "LIDAR", option: str = "lds-port"):
        """`on_open` / `on_close` are written after opening and before closing (e.g. motor start/stop).

        `device` and `option` (the snap option setting `port`) name things in the messages.
        """
        self.port = port
        self.baud = baud
        self.on_open = on_open
        self.on_close = on_close
        self.log = log
        self.clock = clock or time.monotonic
        self.backoff = backoff or Backoff(0.1, 2.0)
        self.serial = None
        self.losses = 0
        self.reconnections = 0
        self.last_error = ""
        self.problem = SerialProblem("", "")  # why the port is not open, and what to do
        self.device = device
        self.option = option
        self._next_attempt = 0.0
        self._reported = False
        self._closed = False  # closed for good (node shutdown): no more reopening, no error reports

    @property
    def is_open(self) -> bool:
        return self.serial is not None

    def _open(self):
        now = self.clock()
        if now < self._next_attempt:
            return False
        try:
            self.serial = serial.Serial(self.port, self.baud, timeout=0.1)
            if self.on_open:
                self.serial.write(self.on_open)
        except DEVICE_ERRORS as error:
            self._close()
            self.last_error = str(error)
            self.problem = explain_open_error(self.port, error, self.device, self.option)
            self._next_attempt = now + self.backoff.next_delay()
            if not self._reported:
                self._report("warning", f"{self.problem.message}: {self.problem.fix}; retrying")
                self._reported = True
            return False
        self.problem = SerialProblem("", "")
        self.backoff.reset()
        if self.losses:
            self.reconnections += 1
            self._report("info", f"{self.port} reopened")
        self._reported = False
        return True

    def read(self, size: int = 4096) -> bytes:
        """Bytes available now (waits up to 0.1 s); b"" while the device is missing."""
        if self._closed or (self.serial is None and not self._open()):
            return b""
        try:
            return self.serial.read(max(1, min(size, self.serial.in_waiting)))
        except DEVICE_ERRORS + (AttributeError, TypeError) as error:  # (closed under our feet at shutdown)
            if self._closed:
                return b""
            self.losses += 1
            self.last_error = str(error)
            self._report("error", f"lost {self.port}: {error}; reopening with backoff")
            self._close()
            self._next_attempt = self.clock() + self.backoff.next_delay()
            self._reported = True
            return b""

    def _close(self):
        if self.serial is not None:
            try:
                self.serial.close()
            except DEVICE_ERRORS:
                pass
        self.serial = None

    def release(self):
        """Close the port for now (another reader needs it); the next read opens it again."""
        self._close()
        self._next_attempt = 0.0

    def close(self):
        self._closed = True
        if self.serial is not None and self.on_close:
            try:
                self.serial.write(self.on_close)
            except DEVICE_ERRORS:
                pass
        self._close()

    def _report(self, level, message):
        if self.log is not None:
            getattr(self.log, level)(message)
