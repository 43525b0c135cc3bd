"""A serial device on a pseudo-terminal, reachable through a symlink (e.g. /tmp/ttyACM0 -> /dev/pts/7).

`plug()` creates the pty and points the symlink at its slave end; `unplug()`
removes the symlink and closes the pty, so a host that had the port open gets
I/O errors, as with a USB cable pulled out. Replugging creates a new pty behind
the same symlink. An unplugged pty's number stays taken until `close()`: a host
still pointed at /dev/pts/N then finds no device, as a robot's /dev/ttyACM0 is
gone when its cable is, instead of opening whatever pty took the number next
(another test's terminal, whose settings it would change). The device keeps
its own slave descriptor open in raw mode so that the line discipline never
echoes or translates bytes, even before the host configures the port. Writes
never block: bytes the host does not read in time are dropped once the pty's
buffer is full, as a serial line would lose them.
"""
import errno
import os
import select
import termios
import tty
from pathlib import Path

# termios speed codes -> bits per second, for the rates pyserial can set
_BAUD_RATES = {getattr(termios, f"B{rate}"): rate for rate in (9600, 19200, 38400, 57600, 115200, 230400,
                                                                 460800, 500000, 576000, 921600, 1000000)
               if hasattr(termios, f"B{rate}")}


class PtyLink:
    def __init__(self, path):
        self.path = Path(path)
        self._master = None
        self._slave = None
        self.slave_name = None
        self.dropped_bytes = 0
        self._unplugged_slaves = []  # held open: the kernel gives a pty's number again once all its ends close

    @property
    def plugged(self) -> bool:
        return self._master is not None

    def plug(self):
        if self.plugged:
            return
        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self.slave_name = os.ttyname(slave)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        temporary = self.path.with_name(f".{self.path.name}.{os.getpid()}.link")
        if os.path.lexists(temporary):
            os.unlink(temporary)
        os.symlink(self.slave_name, temporary)
        os.replace(temporary, self.path)  # atomic: the path never dangles while plugged

    def unplug(self):
        if not self.plugged:
            return
        try:
            if os.path.islink(self.path) and os.readlink(self.path) == self.slave_name:
                os.unlink(self.path)
        except OSError:
            pass
        _close_quietly(self._master)
        self._unplugged_slaves.append(self._slave)
        self._master = self._slave = None

    def close(self):
        """Unplug for good: the numbers of the ptys this link had can now go to new ones."""
        self.unplug()
        for fd in self._unplugged_slaves:
            _close_quietly(fd)
        self._unplugged_slaves = []

    def host_baud(self):
        """The baud rate the host last set on the port (a pty keeps it, though it sends at any rate), or None."""
        if not self.plugged:
            return None
        try:
            return _BAUD_RATES.get(termios.tcgetattr(self._slave)[5])
        except termios.error:
            return None

    def read(self, timeout: float) -> bytes:
        """Bytes the host wrote, waiting at most `timeout` s; b"" when there are none."""
        if not self.plugged:
            return b""
        ready, _, _ = select.select([self._master], [], [], timeout)
        if not ready:
            return b""
        try:
            return os.read(self._master, 4096)
        except BlockingIOError:
            return b""
        except OSError as error:
            if error.errno == errno.EIO:
                return b""
            raise

    def write(self, data: bytes) -> int:
        """Send what fits now; the rest is lost. Returns the number of bytes sent."""
        if not self.plugged or not data:
            return 0
        sent = 0
        try:
            while sent < len(data):
                sent += os.write(self._master, data[sent:])
        except (BlockingIOError, OSError):
            pass
        self.dropped_bytes += len(data) - sent
        return sent


def _close_quietly(fd: int):
    try:
        os.close(fd)
    except OSError:
        pass
