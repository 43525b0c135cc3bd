"""The OpenCR control table spoken by ROBOTIS's current TurtleBot3 firmware.

The OpenCR board answers Dynamixel Protocol 2.0 as a device with ID 200 at
1 Mbps. Its memory is a table of little-endian items; the driver reads the
whole sensor block [10, 182) in one request per cycle and writes velocity
commands, the heartbeat and a few switches. The fake board in turtlebot3c_sim
serves the same table.
"""
import struct
from typing import NamedTuple

DEVICE_ID = 200
BAUD_RATE = 1000000
PROTOCOL_VERSION = 2.0
MODEL_NUMBER = 0x5000

MODEL_INFORMATION_BURGER = 1
MODEL_INFORMATION_WAFFLE = 2


class Item(NamedTuple):
    address: int
    size: int
    format: str  # struct format of the value, little-endian
    writable: bool = False


MODEL_NUMBER_ITEM = Item(0, 2, "<H")
MODEL_INFORMATION = Item(2, 4, "<I")
FIRMWARE_VERSION = Item(6, 1, "<B")
ID = Item(7, 1, "<B")
BAUD_RATE_ITEM = Item(8, 1, "<B")
MILLIS = Item(10, 4, "<I")
MICROS = Item(14, 4, "<I")
DEVICE_STATUS = Item(18, 1, "<b")
HEARTBEAT = Item(19, 1, "<B", writable=True)
EXTERNAL_LED_1 = Item(20, 1, "<B", writable=True)
EXTERNAL_LED_2 = Item(21, 1, "<B", writable=True)
EXTERNAL_LED_3 = Item(22, 1, "<B", writable=True)
EXTERNAL_LED_4 = Item(23, 1, "<B", writable=True)
BUTTON_1 = Item(26, 1, "<B")
BUTTON_2 = Item(27, 1, "<B")
BUMPER_1 = Item(28, 1, "<B")
BUMPER_2 = Item(29, 1, "<B")
ILLUMINATION = Item(30, 4, "<I")
IR = Item(34, 4, "<I")
SONAR = Item(38, 4, "<f")
BATTERY_VOLTAGE = Item(42, 4, "<I")  # V x 100
BATTERY_PERCENTAGE = Item(46, 4, "<I")  # % x 100
SOUND = Item(50, 1, "<B", writable=True)
IMU_RE_CALIBRATION = Item(59, 1, "<B", writable=True)
IMU_ANGULAR_VELOCITY_X = Item(60, 4, "<f")  # rad/s
IMU_ANGULAR_VELOCITY_Y = Item(64, 4, "<f")
IMU_ANGULAR_VELOCITY_Z = Item(68, 4, "<f")
IMU_LINEAR_ACCELERATION_X = Item(72, 4, "<f")  # m/s^2
IMU_LINEAR_ACCELERATION_Y = Item(76, 4, "<f")
IMU_LINEAR_ACCELERATION_Z = Item(80, 4, "<f")
IMU_MAGNETIC_X = Item(84, 4, "<f")
IMU_MAGNETIC_Y = Item(88, 4, "<f")
IMU_MAGNETIC_Z = Item(92, 4, "<f")
IMU_ORIENTATION_W = Item(96, 4, "<f")
IMU_ORIENTATION_X = Item(100, 4, "<f")
IMU_ORIENTATION_Y = Item(104, 4, "<f")
IMU_ORIENTATION_Z = Item(108, 4, "<f")
PRESENT_CURRENT_LEFT = Item(120, 4, "<i")
PRESENT_CURRENT_RIGHT = Item(124, 4, "<i")
PRESENT_VELOCITY_LEFT = Item(128, 4, "<i")  # unit 0.229 rpm
PRESENT_VELOCITY_RIGHT = Item(132, 4, "<i")
PRESENT_POSITION_LEFT = Item(136, 4, "<i")  # encoder ticks, 4096 per turn
PRESENT_POSITION_RIGHT = Item(140, 4, "<i")
MOTOR_CONNECT = Item(148, 1, "<B")
MOTOR_TORQUE_ENABLE = Item(149, 1, "<B", writable=True)
CMD_VELOCITY_LINEAR_X = Item(150, 4, "<i", writable=True)  # m/s x 100
CMD_VELOCITY_LINEAR_Y = Item(154, 4, "<i", writable=True)
CMD_VELOCITY_LINEAR_Z = Item(158, 4, "<i", writable=True)
CMD_VELOCITY_ANGULAR_X = Item(162, 4, "<i", writable=True)  # rad/s x 100
CMD_VELOCITY_ANGULAR_Y = Item(166, 4, "<i", writable=True)
CMD_VELOCITY_ANGULAR_Z = Item(170, 4, "<i", writable=True)
PROFILE_ACCELERATION_LEFT = Item(174, 4, "<I", writable=True)
PROFILE_ACCELERATION_RIGHT = Item(178, 4, "<I", writable=True)

# The block the driver reads every cycle, and the velocity command it writes.
SENSOR_BLOCK_START = MILLIS.address
SENSOR_BLOCK_SIZE = PROFILE_ACCELERATION_RIGHT.address + PROFILE_ACCELERATION_RIGHT.size - SENSOR_BLOCK_START  # 172
CMD_VELOCITY_START = CMD_VELOCITY_LINEAR_X.address
CMD_VELOCITY_SIZE = 24  # six int32: linear x, y, z, angular x, y, z

TABLE_SIZE = PROFILE_ACCELERATION_RIGHT.address + PROFILE_ACCELERATION_RIGHT.size  # 182

# Firmware and wheel constants used to convert table values.
HEARTBEAT_TIMEOUT = 0.5  # s without a heartbeat change before the firmware stops the motors
TICKS_PER_REVOLUTION = 4096
TICK_TO_RAD = 0.001533981  # 2*pi/4096
VELOCITY_UNIT_RPM = 0.229  # present_velocity unit
VELOCITY_SCALE = 100.0  # cmd_velocity items are m/s and rad/s times 100


def decode(item: Item, block: bytes, block_start: int = SENSOR_BLOCK_START):
    """The value of `item` inside `block`, a buffer read from address `block_start`."""
    offset = item.address - block_start
    if offset < 0 or offset + item.size > len(block):
        raise ValueError(f"item at address {item.address} is outside the block read")
    return struct.unpack_from(item.format, block, offset)[0]


def encode(item: Item, value) -> bytes:
    return struct.pack(item.format, value)


def velocity_units(value: float) -> int:
    """`value` in the table's 0.01 units, truncated toward zero so a clamped command stays within its limit.

    (Rounding to 1e-6 first keeps 0.29 from becoming 28 through 28.999999999999996.)
    """
    return int(round(value * VELOCITY_SCALE, 6))


def encode_velocity_command(linear_x: float, angular_z: float) -> bytes:
    """The 24 bytes the driver writes at CMD_VELOCITY_START for a Twist."""
    return struct.pack("<6i", velocity_units(linear_x), 0, 0, 0, 0, velocity_units(angular_z))
