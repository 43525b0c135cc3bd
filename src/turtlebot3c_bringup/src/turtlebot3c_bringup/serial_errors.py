"""What a serial port raises when its device goes away."""
import termios

import serial

# pyserial's own error, plain I/O errors, and termios.error (not an OSError) from flushing a vanished tty.
DEVICE_ERRORS = (OSError, serial.SerialException, termios.error)
