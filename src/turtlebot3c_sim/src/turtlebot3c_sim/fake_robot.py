"""A whole fake TurtleBot3 in one process: the simulation in real time, the OpenCR and the LIDAR on ptys.

The simulation advances with the monotonic clock in a thread of its own
(`RealTimeRobot`); the fake OpenCR (`devices.OpenCRDevice`) and LIDAR
(`devices.LidarDevice`) serve it on pseudo-terminals reached through symlinks,
so a driver opens e.g. `/tmp/x/ttyACM0` as it would open `/dev/ttyACM0`.

Control socket (optional, a Unix stream socket): a client sends one command
per line and gets one line back, `ok` or `ok <JSON>` on success, `error <reason>`
otherwise. Commands:

    status                        JSON: pose, odometry, velocity, collisions, devices and their counters
    pose                          JSON: [x, y, yaw] ground truth in the world frame
    unplug opencr|lds             pull the device's USB cable: the symlink goes, open ports get I/O errors
    replug opencr|lds             plug it back: a new pty behind the same symlink, device at power-on state
    faults opencr|lds SPEC        replace the device's faults, e.g. `faults opencr crc=0.1,garbage=0.01`;
                                  `faults lds none` clears them (see `faults` for the keys)
    teleport X Y YAW              move the robot (ground truth only: odometry does not see it)
    firmware dynamixel|rosserial  flash the OpenCR: the ROS 2 firmware (the default) or the ROS 1 rosserial one
    lidar LDS-01|LDS-02           fit the other LIDAR on the same port (its own protocol and baud rate)
    battery VOLTS                 the battery's voltage (12.0 by default; below 11.0 V for 5 s the motors stop)
    help                          this list

`send_command(socket_path, "unplug opencr")` is a client for tests in other processes.
"""
import json
import os
import socket
import threading
import time
from pathlib import Path

from .devices import LidarDevice, OpenCRDevice
from .fake_opencr import FakeOpenCR
from .faults import LIDAR_FAULTS, OPENCR_FAULTS, FaultError, FaultInjector, parse_faults
from .simulation import NoiseConfig, Simulation
from .world import load_world

STEP_PERIOD = 0.005  # s of real time between simulation steps


class RealTimeRobot:
    """A Simulation advanced in real time, its OpenCR board, and the devices serving them."""

    def __init__(self, world="turtlebot3_world", model="burger", pose=None, seed=0, noise=None,
                 opencr_link=None, lds_link=None, lds_model="LDS-01", opencr_faults="", lds_faults="",
                 opencr_firmware="dynamixel"):
        self.lock = threading.RLock()
        self.world = load_world(world) if isinstance(world, str) else world
        self.sim = Simulation(self.world, model=model, pose=pose, seed=seed,
                              noise=NoiseConfig() if noise is None else noise)
        self.board = FakeOpenCR(self.sim)
        self.devices = {}
        if opencr_link:
            self.devices["opencr"] = OpenCRDevice(
                opencr_link, self, FaultInjector(OPENCR_FAULTS, seed + 1, parse_faults(opencr_faults, OPENCR_FAULTS)),
                firmware=opencr_firmware)
        if lds_link:
            self.devices["lds"] = LidarDevice(
                lds_link, self, lds_model,
                FaultInjector(LIDAR_FAULTS, seed + 2, parse_faults(lds_faults, LIDAR_FAULTS)))
        self._stopping = threading.Event()
        self._stepper = threading.Thread(target=self._run, name="simulation", daemon=True)
        self.steps = 0

    def start(self):
        self._stepper.start()
        for device in self.devices.values():
            device.start()
        for name, device in self.devices.items():
            if not device.wait_plugged(10.0):
                raise RuntimeError(f"fake {name} did not come up on {device.link.path}: {device.error}")
        return self

    def stop(self):
        self._stopping.set()
        for device in self.devices.values():
            device.stop()
        if self._stepper.is_alive():
            self._stepper.join(5.0)

    def _run(self):
        last = time.monotonic()
        while not self._stopping.wait(max(0.0, last + STEP_PERIOD - time.monotonic())):
            now = time.monotonic()
            with self.lock:
                self.sim.step(now - last)
                self.board.update()
            self.steps += 1
            last = now

    # --- control ------------------------------------------------------------------

    def device(self, name):
        try:
            return self.devices[name]
        except KeyError:
            raise ValueError(f"no device {name!r}; this robot has: {', '.join(self.devices) or 'none'}") from None

    def teleport(self, x, y, yaw):
        with self.lock:
            self.sim.teleport(x, y, yaw)

    def snapshot(self) -> dict:
        with self.lock:
            sim = self.sim
            return {"time": sim.time, "pose": list(sim.pose), "velocity": list(sim.velocity),
                    "odometry": list(sim.odometry), "command": list(sim.command),
                    "command_since": sim.command_since,
                    "collided": sim.collided, "in_contact": sim.in_contact, "collisions": sim.collisions,
                    "world": self.world.name, "model": sim.model.name,
                    "battery_voltage": self.board.battery_voltage, "motor_power": self.board.motor_power,
                    "devices": {name: device.status() for name, device in self.devices.items()}}

    def execute(self, line: str) -> str:
        """Run one control command; the reply line (without newline)."""
        words = line.split()
        if not words:
            return "error empty command; try help"
        command, args = words[0], words[1:]
        try:
            if command == "help":
                return "ok " + json.dumps(__doc__.split("Commands:")[1].split("`send_command")[0].strip())
            if command == "status":
                return "ok " + json.dumps(self.snapshot())
            if command == "pose":
                with self.lock:
                    return "ok " + json.dumps(list(self.sim.pose))
            if command in ("unplug", "replug") and len(args) == 1:
                device = self.device(args[0])
                device.unplug() if command == "unplug" else device.replug()
                return "ok"
            if command == "faults" and len(args) in (1, 2):
                spec = args[1] if len(args) == 2 and args[1] != "none" else ""
                self.device(args[0]).faults.configure(spec)
                return "ok"
            if command == "firmware" and len(args) == 1:
                self.device("opencr").flash(args[0])
                return "ok"
            if command == "lidar" and len(args) == 1:
                self.device("lds").swap(args[0])
                return "ok"
            if command == "battery" and len(args) == 1:
                with self.lock:
                    self.board.battery_voltage = float(args[0])
                return "ok"
            if command == "teleport" and len(args) == 3:
                self.teleport(*(float(value) for value in args))
                return "ok"
        except (ValueError, FaultError, TimeoutError) as error:
            return f"error {error}"
        return f"error unknown command or wrong arguments: {line.strip()!r}; try help"


class ControlServer(threading.Thread):
    """Serves `RealTimeRobot.execute` on a Unix socket, one command per line."""

    def __init__(self, path, robot: RealTimeRobot):
        super().__init__(name="control-socket", daemon=True)
        self.path = Path(path)
        self.robot = robot
        if self.path.exists() or self.path.is_symlink():
            self.path.unlink()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._server.bind(str(self.path))
        self._server.listen(8)

    def run(self):
        while True:
            try:
                connection, _ = self._server.accept()
            except OSError:
                return  # closed
            threading.Thread(target=self._serve, args=(connection,), daemon=True).start()

    def _serve(self, connection):
        with connection, connection.makefile("rw") as stream:
            for line in stream:
                stream.write(self.robot.execute(line) + "\n")
                stream.flush()

    def close(self):
        self._server.close()
        try:
            os.unlink(self.path)
        except OSError:
            pass


class ControlError(RuntimeError):
    pass


def send_command(socket_path, command: str, timeout: float = 10.0):
    """Send one control command; the decoded JSON reply (or None for a bare `ok`). Raises ControlError."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as client:
        client.settimeout(timeout)
        client.connect(str(socket_path))
        client.sendall(command.encode() + b"\n")
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = client.recv(65536)
            if not chunk:
                break
            reply += chunk
    text = reply.decode().strip()
    if text == "ok":
        return None
    if text.startswith("ok "):
        return json.loads(text[3:])
    raise ControlError(text[len("error "):] if text.startswith("error ") else f"bad reply {text!r}")


def parse_fault_options(items):
    """`["opencr:crc=0.1", "lds:garbage=0.01"]` -> {"opencr": "crc=0.1", "lds": "garbage=0.01"}."""
    specs = {"opencr": "", "lds": ""}
    for item in items or []:
        device, separator, spec = item.partition(":")
        if not separator or device not in specs:
            raise FaultError(f"--faults {item!r}: expected opencr:KEY=P,... or lds:KEY=P,...")
        parse_faults(spec, OPENCR_FAULTS if device == "opencr" else LIDAR_FAULTS)
        specs[device] = ",".join(filter(None, (specs[device], spec)))
    return specs

