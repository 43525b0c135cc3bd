"""The OpenCR board as the TurtleBot3 ROS 2 firmware presents it: a Dynamixel 2.0 device at ID 200.

The board serves the control table of `turtlebot3c_bringup.opencr_control_table`
backed by a `Simulation`: sensor items are refreshed from it before every
reply, and writes drive it. As the firmware does:
- cmd_velocity_linear_x (150) and cmd_velocity_angular_z (170), m/s and rad/s x 100,
  set the goal velocity, clamped to the model's limits; the other four are stored only;
- each wheel is then clamped to the Dynamixel's goal velocity limit (337 x 0.229 rpm),
  so driving at full speed leaves no room to turn (the curve flattens, as on the robot);
- the heartbeat (19) must change at least every 0.5 s, or the goal velocity is
  zeroed (and stays zero until the next velocity write);
- motor_torque_enable (149) = 0 stops the wheels and ignores velocity commands;
- imu_re_calibration (59) = 1 recalibrates the gyro and reads back 0 afterwards;
- sound (50) plays a melody (recorded in `sounds`);
- writes to read-only items are refused with an access error and change nothing;
- the battery voltage (`battery_voltage`, settable) below 11.0 V for 5 s switches the
  motors' power off until it is back above 11.0 V (updateVoltageCheck's cut-off).
All times are the simulation's. This module does no I/O: `handle(packet)` returns the reply bytes.
"""
import math
import struct
from typing import List, Optional

from turtlebot3c_bringup import opencr_control_table as table

from . import dynamixel_protocol as dxl
from .simulation import Simulation

FIRMWARE_VERSION = 5  # the ROS 2 firmware's FIRMWARE_VER
BAUD_RATE_INDEX = 3  # Dynamixel baud rate index of 1 Mbps
BATTERY_VOLTAGE = 12.0  # V, a charged 3-cell pack
BATTERY_EMPTY, BATTERY_FULL = 10.5, 12.3  # V, the firmware's percentage range
BATTERY_CUTOFF, BATTERY_CUTOFF_DELAY = 11.0, 5.0  # V, s: the firmware's motor power cut-off
GOAL_VELOCITY_LIMIT = 337  # the firmware's clamp of each wheel's Goal_Velocity, in 0.229 rpm units


def _items():
    return [value for value in vars(table).values() if isinstance(value, table.Item)]


def _writable_addresses():
    return frozenset(address for item in _items() if item.writable
                     for address in range(item.address, item.address + item.size))


WRITABLE = _writable_addresses()
VELOCITY_COMMAND = range(table.CMD_VELOCITY_START, table.CMD_VELOCITY_START + table.CMD_VELOCITY_SIZE)


class FakeOpenCR:
    def __init__(self, simulation: Simulation):
        self.sim = simulation
        self.memory = bytearray(table.TABLE_SIZE)
        self.sounds: List[int] = []
        self.calibrations = 0
        self.heartbeat_stalls = 0
        self.stalled_at = None  # simulated time the last heartbeat stall stopped the motors
        self.requests = 0
        self._goal = (0.0, 0.0)
        self.battery_voltage = BATTERY_VOLTAGE
        self.motor_power = True
        self._low_since = None
        self._last_heartbeat_change = simulation.time
        self._stalled = False
        self._put(table.MODEL_NUMBER_ITEM, table.MODEL_NUMBER)
        model_information = table.MODEL_INFORMATION_BURGER if simulation.model.name == "burger" \
            else table.MODEL_INFORMATION_WAFFLE
        self._put(table.MODEL_INFORMATION, model_information)
        self._put(table.FIRMWARE_VERSION, FIRMWARE_VERSION)
        self._put(table.ID, table.DEVICE_ID)
        self._put(table.BAUD_RATE_ITEM, BAUD_RATE_INDEX)
        self._put(table.MOTOR_CONNECT, 1)
        self._put(table.MOTOR_TORQUE_ENABLE, 1)
        self.update()

    # --- state -------------------------------------------------------------------

    def _put(self, item, value):
        struct.pack_into(item.format, self.memory, item.address, value)

    def get(self, item):
        return struct.unpack_from(item.format, self.memory, item.address)[0]

    @property
    def torque_enabled(self) -> bool:
        return bool(self.memory[table.MOTOR_TORQUE_ENABLE.address])

    @property
    def heartbeat_alive(self) -> bool:
        return self.sim.time - self._last_heartbeat_change < table.HEARTBEAT_TIMEOUT

    @property
    def goal_velocity(self):
        return self._goal

    def update(self):
        """The firmware's cycle: stop on a stalled heartbeat, drive the motors, refresh the sensor items."""
        if not self.heartbeat_alive and not self._stalled:
            self._stalled = True
            self.heartbeat_stalls += 1
            self.stalled_at = self.sim.time
            self._goal = (0.0, 0.0)
        self._check_battery()
        self._drive()
        self._refresh_sensors()

    def _check_battery(self):
        if self.battery_voltage >= BATTERY_CUTOFF:
            self._low_since = None
            self.motor_power = True
            return
        if self._low_since is None:
            self._low_since = self.sim.time
        if self.sim.time - self._low_since >= BATTERY_CUTOFF_DELAY:
            self.motor_power = False

    def _drive(self):
        if self.torque_enabled and self.motor_power:
            self.sim.set_command(*driven_velocity(self._goal, self.sim.model))
        else:
            self.sim.stop()

    def _refresh_sensors(self):
        sim = self.sim
        now = sim.time
        self._put(table.MILLIS, int(now * 1000.0) & 0xFFFFFFFF)
        self._put(table.MICROS, int(now * 1e6) & 0xFFFFFFFF)
        self._put(table.DEVICE_STATUS, 0)
        self._put(table.BATTERY_VOLTAGE, int(round(self.battery_voltage * 100)))
        percentage = (self.battery_voltage - BATTERY_EMPTY) / (BATTERY_FULL - BATTERY_EMPTY) * 100.0
        self._put(table.BATTERY_PERCENTAGE, int(round(max(0.0, min(100.0, percentage)) * 100)))
        imu = sim.imu()
        self._put(table.IMU_ANGULAR_VELOCITY_X, imu.angular_velocity_x)
        self._put(table.IMU_ANGULAR_VELOCITY_Y, imu.angular_velocity_y)
        self._put(table.IMU_ANGULAR_VELOCITY_Z, imu.angular_velocity_z)
        self._put(table.IMU_LINEAR_ACCELERATION_X, imu.linear_acceleration_x)
        self._put(table.IMU_LINEAR_ACCELERATION_Y, imu.linear_acceleration_y)
        self._put(table.IMU_LINEAR_ACCELERATION_Z, imu.linear_acceleration_z)
        w, x, y, z = imu.orientation_quaternion
        self._put(table.IMU_ORIENTATION_W, w)
        self._put(table.IMU_ORIENTATION_X, x)
        self._put(table.IMU_ORIENTATION_Y, y)
        self._put(table.IMU_ORIENTATION_Z, z)
        for position_item, velocity_item, angle, rate in zip(
                (table.PRESENT_POSITION_LEFT, table.PRESENT_POSITION_RIGHT),
                (table.PRESENT_VELOCITY_LEFT, table.PRESENT_VELOCITY_RIGHT),
                sim.wheel_positions, sim.wheel_velocities):
            ticks = int(round(angle / (2.0 * math.pi) * table.TICKS_PER_REVOLUTION))
            self._put(position_item, _int32(ticks))
            self._put(velocity_item, _int32(int(round(rate * 60.0 / (2.0 * math.pi) / table.VELOCITY_UNIT_RPM))))
        if self.memory[table.IMU_RE_CALIBRATION.address]:
            self.memory[table.IMU_RE_CALIBRATION.address] = 0  # calibration done

    # --- protocol ----------------------------------------------------------------

    def handle(self, packet: dxl.Packet) -> Optional[bytes]:
        """The reply to one instruction packet, or None when the board stays silent."""
        addressed = packet.device_id == table.DEVICE_ID
        broadcast = packet.device_id == dxl.BROADCAST_ID
        if not (addressed or broadcast):
            return None
        self.requests += 1
        self.update()
        if packet.instruction == dxl.PING:
            params = struct.pack("<HB", table.MODEL_NUMBER, FIRMWARE_VERSION)
            return dxl.status_packet(table.DEVICE_ID, dxl.ERROR_NONE, params)
        if packet.instruction == dxl.SYNC_READ:
            return self._sync_read(packet.params)
        if packet.instruction == dxl.SYNC_WRITE:
            self._sync_write(packet.params)
            return None
        if broadcast:
            return None
        if packet.instruction == dxl.READ:
            error, data = self._read(packet.params)
            return dxl.status_packet(table.DEVICE_ID, error, data)
        if packet.instruction == dxl.WRITE:
            return dxl.status_packet(table.DEVICE_ID, self._write(packet.params))
        if packet.instruction == dxl.REBOOT:
            return dxl.status_packet(table.DEVICE_ID)
        return dxl.status_packet(table.DEVICE_ID, dxl.ERROR_INSTRUCTION)

    def _read(self, params):
        if len(params) != 4:
            return dxl.ERROR_DATA_LENGTH, b""
        address, length = struct.unpack("<HH", params)
        if length == 0 or address + length > table.TABLE_SIZE:
            return dxl.ERROR_DATA_RANGE, b""
        return dxl.ERROR_NONE, bytes(self.memory[address:address + length])

    def _sync_read(self, params):
        if len(params) < 5 or table.DEVICE_ID not in params[4:]:
            return None
        error, data = self._read(params[:4])
        return dxl.status_packet(table.DEVICE_ID, error, data)

    def _sync_write(self, params):
        if len(params) < 4:
            return
        length = struct.unpack_from("<H", params, 2)[0]
        stride = 1 + length
        for offset in range(4, len(params) - stride + 1, stride):
            if params[offset] == table.DEVICE_ID:
                self._write(params[:2] + params[offset + 1:offset + stride])

    def _write(self, params) -> int:
        if len(params) < 3:
            return dxl.ERROR_DATA_LENGTH
        address = struct.unpack_from("<H", params)[0]
        data = bytes(params[2:])
        end = address + len(data)
        if end > table.TABLE_SIZE:
            return dxl.ERROR_DATA_RANGE
        if any(byte not in WRITABLE for byte in range(address, end)):
            return dxl.ERROR_ACCESS
        heartbeat_before = self.memory[table.HEARTBEAT.address]
        self.memory[address:end] = data
        written = range(address, end)
        if table.HEARTBEAT.address in written and self.memory[table.HEARTBEAT.address] != heartbeat_before:
            self._last_heartbeat_change = self.sim.time
            self._stalled = False
        if any(byte in VELOCITY_COMMAND for byte in written):
            self._goal = (self.get(table.CMD_VELOCITY_LINEAR_X) / table.VELOCITY_SCALE,
                          self.get(table.CMD_VELOCITY_ANGULAR_Z) / table.VELOCITY_SCALE)
            if not self.heartbeat_alive:
                self._goal = (0.0, 0.0)
        if table.IMU_RE_CALIBRATION.address in written and self.memory[table.IMU_RE_CALIBRATION.address]:
            self.calibrations += 1
        if table.SOUND.address in written:
            self.sounds.append(self.memory[table.SOUND.address])
        self._drive()
        return dxl.ERROR_NONE


def _int32(value: int) -> int:
    return (value + 2 ** 31) % 2 ** 32 - 2 ** 31


def driven_velocity(goal, model):
    """The body velocity the firmware drives for a goal: clamped to the model's limits, as the write
    callbacks do, then each wheel clamped to the Goal_Velocity limit."""
    linear = max(-model.max_linear_velocity, min(model.max_linear_velocity, goal[0]))
    angular = max(-model.max_angular_velocity, min(model.max_angular_velocity, goal[1]))
    limit = model.wheel_radius * 2.0 * math.pi * GOAL_VELOCITY_LIMIT * table.VELOCITY_UNIT_RPM / 60.0  # m/s
    half_track = model.wheel_separation / 2.0
    left = max(-limit, min(limit, linear - angular * half_track))
    right = max(-limit, min(limit, linear + angular * half_track))
    return (left + right) / 2.0, (right - left) / (2.0 * half_track)
