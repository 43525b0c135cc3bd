"""Single-key input from a terminal, and getting the terminal back the way it was.

The key mode turns off line buffering, echo and the terminal's own signal keys,
so every key, Ctrl-C included, arrives as a byte the moment it is pressed.
Output processing stays on: `\\n` still starts a new line. Whatever ends the
program (a quit key, a signal, an exception, the terminal going away), the
saved attributes are put back.
"""
import contextlib
import os
import select
import signal
import termios
from typing import Iterator

_LFLAG = 3
_IFLAG = 0
_CC = 6


class TerminalClosed(Exception):
    """The terminal hung up or reached end of input: there will be no more keys."""


class ExitRequested(Exception):
    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def key_mode_attributes(attributes: list) -> list:
    mode = [list(item) if isinstance(item, list) else item for item in attributes]
    mode[_LFLAG] &= ~(termios.ICANON | termios.ECHO | termios.ISIG | termios.IEXTEN)
    mode[_IFLAG] &= ~(termios.IXON | termios.ICRNL)
    mode[_CC][termios.VMIN] = 1
    mode[_CC][termios.VTIME] = 0
    return mode


@contextlib.contextmanager
def key_mode(fd: int) -> Iterator[None]:
    saved = termios.tcgetattr(fd)
    termios.tcsetattr(fd, termios.TCSANOW, key_mode_attributes(saved))
    try:
        yield
    finally:
        restore(fd, saved)


def restore(fd: int, attributes: list) -> bool:
    """Put `attributes` back; False when the terminal is gone and there is nothing to restore."""
    try:
        termios.tcsetattr(fd, termios.TCSANOW, attributes)
        return True
    except (termios.error, OSError):
        return False


def read_input(fd: int, timeout: float) -> str:
    """What the terminal sent within `timeout` seconds (possibly nothing); TerminalClosed when input ended."""
    ready, _, _ = select.select([fd], [], [], max(0.0, timeout))
    if not ready:
        return ""
    try:
        data = os.read(fd, 64)
    except OSError as error:  # EIO: the terminal hung up
        raise TerminalClosed(str(error)) from None
    if not data:
        raise TerminalClosed("end of input")
    return data.decode("latin-1")


def raise_on_signals(*signums: int) -> None:
    """Turn each signal into ExitRequested, once: a second signal during cleanup is ignored."""
    def handler(signum, _frame):
        for each in signums:
            signal.signal(each, signal.SIG_IGN)
        raise ExitRequested(signum)
    for signum in signums:
        signal.signal(signum, handler)
