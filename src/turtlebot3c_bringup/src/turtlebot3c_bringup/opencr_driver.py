"""The OpenCR driver's behaviour, without ROS: connect, poll, command, keep alive, recover.

The node calls `cycle()` from one I/O thread at the read rate and `command()`
from its /cmd_vel callback; everything it publishes comes from the fresh
`Reading` that `cycle()` returns, so nothing stale is ever published while the
link is down. On a lost link the driver closes the port and retries with an
exponential backoff; on reconnection the odometry takes the first reading as
its new baseline, so it resumes from the last pose without a jump.
"""
import time
from typing import NamedTuple, Optional

from turtlebot3c_bringup.opencr_control_table import encode_velocity_command
from turtlebot3c_bringup.opencr_firmware import FLASH_HINT, wrong_firmware_message
from turtlebot3c_bringup.opencr_link import LinkError, LinkLost
from turtlebot3c_bringup.opencr_sensors import SensorState, check_device, decode_sensor_block
from turtlebot3c_bringup.velocity_command import clamp_to_model
from turtlebot3c_bringup.wheel_odometry import Snapshot, WheelOdometry
from turtlebot3c_common.backoff import Backoff
from turtlebot3c_description.models import RobotModel

HEARTBEAT_PERIOD = 0.1  # s; the firmware stops the motors after 0.5 s without a heartbeat change
# s of /cmd_vel silence before the driver commands zero velocity: as short as the teleop watchdog's, so a dead
# teleop daemon (or anything that stops /cmd_vel) stops the robot as fast as a dead velocity source does
COMMAND_TIMEOUT = 0.3
MAX_CONSECUTIVE_FAILURES = 10  # failed reads in a row that mean the link is gone, not just noisy
# s between listens for another firmware on a board that keeps ignoring pings (each takes a few seconds),
# and between repeats of the error naming it: once at once, then seldom enough not to flood the log
FIRMWARE_PROBE_INTERVAL = 30.0
NO_ANSWER_FIX = ("check that the board is powered and that opencr-port is its port "
                 "(sudo snap set turtlebot3c opencr-port=/dev/...)")


class Reading(NamedTuple):
    stamp: float  # the driver clock's time of the read
    sensors: SensorState
    odometry_updated: bool  # False for a baseline reading (first one after a (re)connection)


class SavedOdometry(NamedTuple):
    """The odometry as a restarted driver can resume it, with the board clock it was read at."""
    odometry: Snapshot
    board_millis: int


def saved_odometry_to_dict(saved: SavedOdometry) -> dict:
    """Plain values for the parameter server (no None: XML-RPC has no null)."""
    values = {key: value for key, value in saved.odometry._asdict().items() if value is not None}
    values["board_millis"] = saved.board_millis
    return values


def saved_odometry_from_dict(values) -> SavedOdometry:
    """The inverse of saved_odometry_to_dict; ValueError when `values` is not one."""
    try:
        fields = {name: values.get(name) for name in Snapshot._fields}
        numbers = {name: float(value) for name, value in fields.items()
                   if name not in ("left_ticks", "right_ticks", "imu_yaw")}
        snapshot = Snapshot(left_ticks=int(fields["left_ticks"]), right_ticks=int(fields["right_ticks"]),
                            imu_yaw=None if fields["imu_yaw"] is None else float(fields["imu_yaw"]), **numbers)
        return SavedOdometry(snapshot, int(values["board_millis"]))
    except (AttributeError, KeyError, TypeError, ValueError) as error:
        raise ValueError(f"not a saved odometry: {values!r} ({error})") from None


class LinkStatistics:
    def __init__(self):
        self.reads = 0
        self.writes = 0
        self.errors = {}
        self.link_losses = 0
        self.reconnections = 0
        self.last_error = ""

    def count_error(self, kind: str, message: str):
        self.errors[kind] = self.errors.get(kind, 0) + 1
        self.last_error = message

    @property
    def total_errors(self) -> int:
        return sum(self.errors.values())


class _PrintLog:
    def info(self, message):
        print(message)

    warning = error = info


class OpenCRDriver:
    def __init__(self, link, model: RobotModel, use_imu_yaw: bool = True, clock=time.monotonic, log=None,
                 command_timeout: float = COMMAND_TIMEOUT, backoff: Optional[Backoff] = None,
                 resume: Optional[SavedOdometry] = None, firmware_probe=None):
        """`resume`: the `saved_odometry` of a driver that died, to continue its odometry without a jump.

        `firmware_probe(port_name)`: what other firmware, if any, talks on a port whose board ignores
        pings (an `opencr_firmware.OtherFirmware` or None); the port is closed while it runs.
        """
        self.link = link
        self.model = model
        self.clock = clock
        self.log = log or _PrintLog()
        self.command_timeout = command_timeout
        self.backoff = backoff or Backoff()
        self.stats = LinkStatistics()
        self.odometry = WheelOdometry(model.wheel_radius, model.wheel_separation,
                                      model.max_linear_velocity / model.wheel_radius, use_imu_yaw=use_imu_yaw)
        self.device_info = None
        self.connected = False
        self.problem = ""  # while not connected: why, in one line ...
        self.fix = ""  # ... and the one thing the owner can do about it
        self.other_firmware = None  # the firmware found instead of ours, if any
        self.firmware_probe = firmware_probe
        self._next_probe = 0.0
        self.saved_odometry = None  # refreshed after every reading
        self._resume = resume
        self._next_attempt = 0.0
        self._lost_since = None
        self._attempts = 0
        self._failures = 0
        self._heartbeat = 0
        self._next_heartbeat = 0.0
        self._last_command_time = None
        self._moving = False

    # --- connection ---------------------------------------------------------------------

    def _connect(self, now):
        self._attempts += 1
        try:
            self.link.open()
            self.link.ping()
            info = self.link.read_device_info()
        except LinkError as error:
            self.link.close()
            if error.kind != "device_error" and self._found_other_firmware(now):
                return
            self._retry_later(now, f"{error} (no answer at ID {self.link.device_id}: is the board flashed with "
                                   "ROBOTIS's ROS 2 TurtleBot3 firmware, which speaks Dynamixel Protocol 2.0? "
                                   "The ROS 1 rosserial firmware does not; see the README)", fix=NO_ANSWER_FIX)
            return
        except LinkLost as error:
            self.link.close()
            self._retry_later(now, str(error), fix=error.fix)
            return
        fatal, warnings = check_device(info, self.model.name)
        if fatal:
            self.link.close()
            self._retry_later(now, "; ".join(fatal), level="error", fix=FLASH_HINT)
            return
        for warning in warnings:
            self.log.warning(warning)
        self.device_info = info
        self.other_firmware = None
        self.problem = self.fix = ""
        self._failures = 0
        self.odometry.rebaseline()
        self.backoff.reset()
        self._next_heartbeat = now
        self._safe_write(lambda: self.link.write_velocity(encode_velocity_command(0.0, 0.0)))
        self._moving = False
        if self._lost_since is None:
            self.log.info(f"OpenCR on {self.link.port_name}: firmware version {info.firmware_version}, "
                          f"model information {info.model_information}")
        else:
            self.stats.reconnections += 1
            self.log.info(f"OpenCR link on {self.link.port_name} restored after {now - self._lost_since:.1f} s "
                          f"({self._attempts} attempts); odometry continues from the last pose")
        self._lost_since = None
        self._attempts = 0
        self.connected = True

    def _found_other_firmware(self, now) -> bool:
        """Listen for another firmware on a board that ignored the ping (now and then, not at every retry).

        True when one was found this time or before: the retry is then scheduled and reported here,
        as an error naming it, once and again every FIRMWARE_PROBE_INTERVAL.
        """
        if self.firmware_probe is None:
            return False
        if now < self._next_probe:
            return self.other_firmware is not None and self._schedule_retry(now)
        found = self.firmware_probe(self.link.port_name)
        now = self.clock()  # listening took a while
        self._next_probe = now + FIRMWARE_PROBE_INTERVAL
        self.other_firmware = found
        if found is None:
            return False
        self._schedule_retry(now)
        self.problem = wrong_firmware_message(self.link.port_name, found)
        self.fix = FLASH_HINT
        self.stats.last_error = self.problem
        self.log.error(f"{self.problem}: {self.fix}; retrying every {FIRMWARE_PROBE_INTERVAL:.0f} s")
        return True

    def _schedule_retry(self, now) -> bool:
        self._next_attempt = now + self.backoff.next_delay()
        return True

    def _retry_later(self, now, reason, level="warning", fix=""):
        delay = self.backoff.next_delay()
        self._next_attempt = now + delay
        self.stats.last_error = reason
        self.problem, self.fix = reason, fix
        if self._attempts == 1 or level == "error":
            getattr(self.log, level)(f"cannot reach the OpenCR on {self.link.port_name}: {reason}; "
                                     f"retrying (backoff up to {self.backoff.maximum:.1f} s)")

    def _lose(self, now, reason):
        self.stats.link_losses += 1
        self.stats.last_error = reason
        self.link.close()
        self._lost_since = now
        self._attempts = 0
        self._next_attempt = now + self.backoff.next_delay()
        self.problem, self.fix = f"link lost: {reason}", "check the OpenCR's USB cable and power"
        self.log.error(f"OpenCR link lost on {self.link.port_name}: {reason}; "
                       "odometry paused, reconnecting with backoff")
        self.connected = False

    # --- the I/O cycle ----------------------------------------------------------------------

    def cycle(self) -> Optional[Reading]:
        """One read cycle: a fresh Reading, or None while the link is down or the read failed."""
        now = self.clock()
        if not self.connected:
            if now >= self._next_attempt:
                self._connect(now)
            if not self.connected:
                return None
        reading = self._read(now)
        if self.connected:
            self._keep_alive(now)
        return reading

    def _read(self, now):
        try:
            block = self.link.read_sensor_block()
        except LinkLost as error:
            self._lose(now, str(error))
            return None
        except LinkError as error:
            self.stats.count_error(error.kind, str(error))
            self._failures += 1
            if self._failures >= MAX_CONSECUTIVE_FAILURES:
                self._lose(now, f"{self._failures} reads in a row failed, last: {error}")
            return None
        except Exception as error:  # whatever the SDK trips over: reopen the port rather than die
            self._lose(now, f"unexpected {type(error).__name__}: {error}")
            return None
        self._failures = 0
        self.stats.reads += 1
        sensors = decode_sensor_block(block)
        if self._resume is not None:
            # The board's clock only runs on while it has not been reset: then its counters are the same.
            self.odometry.restore(self._resume.odometry, same_encoders=sensors.millis >= self._resume.board_millis)
            self._resume = None
        updated = self.odometry.update(sensors.encoder_ticks[0], sensors.encoder_ticks[1], now, sensors.imu_yaw)
        snapshot = self.odometry.snapshot()
        if snapshot is not None:
            self.saved_odometry = SavedOdometry(snapshot, sensors.millis)
        return Reading(now, sensors, updated)

    def _keep_alive(self, now):
        if now >= self._next_heartbeat:
            self._heartbeat = (self._heartbeat + 1) & 0xFF
            self._next_heartbeat = now + HEARTBEAT_PERIOD
            self._safe_write(lambda: self.link.write_heartbeat(self._heartbeat))
        if self._moving and now - self._last_command_time >= self.command_timeout:
            self.log.warning(f"no /cmd_vel for {self.command_timeout:.2f} s: stopping the robot")
            self._write_command(0.0, 0.0)

    def _safe_write(self, write) -> bool:
        try:
            write()
        except (LinkError, LinkLost) as error:
            kind = error.kind if isinstance(error, LinkError) else "lost"
            self.stats.count_error(kind, str(error))
            return False
        self.stats.writes += 1
        return True

    def _write_command(self, linear, angular) -> bool:
        ok = self._safe_write(lambda: self.link.write_velocity(encode_velocity_command(linear, angular)))
        if ok:
            self._moving = linear != 0.0 or angular != 0.0
        return ok

    # --- commands ---------------------------------------------------------------------------

    def command(self, linear_x: float, angular_z: float):
        """A /cmd_vel: clamp to the model's limits and write it now. Returns the clamped pair."""
        linear, angular = clamp_to_model(self.model, linear_x, angular_z)
        self._last_command_time = self.clock()
        if self.connected:
            self._write_command(linear, angular)
        return linear, angular

    def set_torque(self, enabled: bool) -> bool:
        return self.connected and self._safe_write(lambda: self.link.write_torque(enabled))

    def shutdown(self):
        if self.connected:
            self._write_command(0.0, 0.0)
        self.link.close()
        self.connected = False
