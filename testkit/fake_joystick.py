"""A joystick the tests plug and unplug: a fake /dev/input/jsN speaking the kernel's js_event structs."""
import os
import tty

from turtlebot3c_teleop.joystick_device import JS_EVENT_AXIS, JS_EVENT_BUTTON, JS_EVENT_INIT, JsEvent, encode_event

FULL = 32767  # an axis pushed all the way


class FakeJoystick:
    """A joystick device the test plugs and unplugs: a raw pseudo-terminal behind a symlink.

    Like a real /dev/input/jsN, reads block until the 'driver' (the test) writes
    js_event structs, and once unplugged reads fail and the path is gone.
    """

    def __init__(self, path):
        self.path = str(path)
        self.master_fd = self.slave_fd = None
        self.time_ms = 1000

    def plug(self, axes=(0,) * 6, buttons=(0,) * 11):
        """Appear at `path` and queue the init events a driver sends on open."""
        self.master_fd, self.slave_fd = os.openpty()
        tty.setraw(self.slave_fd)
        os.symlink(os.ttyname(self.slave_fd), self.path)
        events = [self.event(JS_EVENT_AXIS | JS_EVENT_INIT, value, number) for number, value in enumerate(axes)]
        events += [self.event(JS_EVENT_BUTTON | JS_EVENT_INIT, value, number) for number, value in enumerate(buttons)]
        self.write(events)

    def event(self, type_, value, number):
        self.time_ms += 10
        return JsEvent(self.time_ms, value, type_, number)

    def write(self, events):
        os.write(self.master_fd, b"".join(encode_event(event) for event in events))

    def axis(self, number, value):
        self.write([self.event(JS_EVENT_AXIS, value, number)])

    def button(self, number, pressed):
        self.write([self.event(JS_EVENT_BUTTON, 1 if pressed else 0, number)])

    def plugged(self):
        return self.master_fd is not None

    def unplug(self):
        os.unlink(self.path)
        os.close(self.master_fd)
        os.close(self.slave_fd)
        self.master_fd = self.slave_fd = None

    def close(self):
        if self.master_fd is not None:
            self.unplug()
