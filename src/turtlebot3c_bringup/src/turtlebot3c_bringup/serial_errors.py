"""What a serial port raises when its device goes away, and what to tell the owner when it cannot be opened."""
import errno
import termios
from typing import NamedTuple

import serial

# pyserial's own error, plain I/O errors, and termios.error (not an OSError) from flushing a vanished tty.
DEVICE_ERRORS = (OSError, serial.SerialException, termios.error)

RAW_USB_FIX = "sudo snap connect turtlebot3c:raw-usb"
_ABSENT = (errno.ENOENT, errno.ENODEV, errno.ENXIO)
_DENIED = (errno.EACCES, errno.EPERM)


class SerialProblem(NamedTuple):
    message: str  # what is wrong, in one line
    fix: str  # the one thing to do about it


def explain_open_error(port: str, error: Exception, device: str, option: str) -> SerialProblem:
    """Why `port` (the `device`'s, set by the snap option `option`) did not open, and what to do.

    pyserial keeps the errno of the failed open(2); strict confinement without the raw-usb
    connection shows as EACCES/EPERM, an unplugged device as ENOENT.
    """
    code = getattr(error, "errno", None)
    if code is None and error.args and isinstance(error.args[0], int):
        code = error.args[0]
    if code in _DENIED:
        return SerialProblem(f"not permitted to open {port} (the {device}'s serial port)", RAW_USB_FIX)
    if code in _ABSENT:
        return SerialProblem(f"no {device} at {port}",
                             f"plug the {device} in, or set its port: sudo snap set turtlebot3c {option}=/dev/...")
    return SerialProblem(f"cannot open {port} (the {device}'s serial port): {error}",
                         f"check the {device}'s cable and `{option}`")
