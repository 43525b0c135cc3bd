"""A process whose controlling terminal is a pseudo-terminal the test types into (the key app's tests)."""
import fcntl
import os
import select
import signal
import subprocess
import termios
import threading


def _take_terminal():
    # Runs in the child after setsid(): make the pseudo-terminal on stdin its controlling terminal.
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


class PtySession:
    """A process whose controlling terminal is a fresh pseudo-terminal that the test types into."""

    def __init__(self, env, args):
        self.master_fd, self.slave_fd = os.openpty()
        self.original = termios.tcgetattr(self.slave_fd)
        self._output = bytearray()
        self._lock = threading.Lock()
        self._reading = True
        self.process = subprocess.Popen(
            [str(arg) for arg in args], env=env, stdin=self.slave_fd, stdout=self.slave_fd,
            stderr=self.slave_fd, start_new_session=True, preexec_fn=_take_terminal)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        while self._reading:
            try:
                ready, _, _ = select.select([self.master_fd], [], [], 0.1)
                if ready:
                    data = os.read(self.master_fd, 4096)
                    with self._lock:
                        self._output.extend(data)
            except OSError:
                return

    def text(self):
        with self._lock:
            return self._output.decode(errors="replace")

    def type(self, keys):
        os.write(self.master_fd, keys.encode())

    def attributes(self):
        return termios.tcgetattr(self.slave_fd)

    def in_key_mode(self):
        return not self.attributes()[3] & termios.ICANON

    def hang_up(self):
        """Close the terminal's master side, as a terminal window being closed does."""
        self._reading = False
        self._reader.join(2)
        os.close(self.master_fd)
        self.master_fd = None

    def wait_exit(self, timeout=30):
        try:
            return self.process.wait(timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"process did not exit within {timeout} s; output:\n{self.text()}") from None

    def close(self):
        try:
            os.killpg(self.process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.process.wait(5)
        self._reading = False
        self._reader.join(2)
        for fd in (self.master_fd, self.slave_fd):
            if fd is not None:
                os.close(fd)
