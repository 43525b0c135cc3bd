"""Decode the OpenCR sensor block (one READ of the control table per cycle) into values in SI units."""
import math
from typing import NamedTuple, Tuple

from turtlebot3c_bringup import opencr_control_table as table

VELOCITY_UNIT_RAD_S = table.VELOCITY_UNIT_RPM * 2.0 * math.pi / 60.0  # present_velocity unit in rad/s
BATTERY_PRESENT_VOLTAGE = 7.0  # V; below this the board runs from USB only


class SensorState(NamedTuple):
    millis: int
    device_status: int  # 0 running, -1 motors not connected
    buttons: Tuple[bool, bool]
    bumpers: Tuple[bool, bool]
    illumination: int
    ir: int
    sonar: float
    battery_voltage: float  # V
    battery_percentage: float  # 0..100
    angular_velocity: Tuple[float, float, float]  # rad/s
    linear_acceleration: Tuple[float, float, float]  # m/s^2
    magnetic_field: Tuple[float, float, float]
    orientation: Tuple[float, float, float, float]  # quaternion x, y, z, w
    present_current: Tuple[int, int]  # left, right, raw
    wheel_velocity: Tuple[float, float]  # left, right, rad/s
    encoder_ticks: Tuple[int, int]  # left, right
    motor_connected: bool
    torque_enabled: bool

    @property
    def battery_present(self) -> bool:
        return self.battery_voltage > BATTERY_PRESENT_VOLTAGE

    @property
    def imu_yaw(self):
        """Heading from the IMU quaternion, or None when the board reports no valid orientation."""
        x, y, z, w = self.orientation
        norm = math.sqrt(x * x + y * y + z * z + w * w)
        if not math.isfinite(norm) or abs(norm - 1.0) > 0.1:
            return None
        return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _vector(block, *items):
    return tuple(table.decode(item, block) for item in items)


def decode_sensor_block(block: bytes) -> SensorState:
    """Decode the SENSOR_BLOCK_SIZE bytes read at SENSOR_BLOCK_START; ValueError if the size is wrong."""
    if len(block) != table.SENSOR_BLOCK_SIZE:
        raise ValueError(f"sensor block has {len(block)} bytes, expected {table.SENSOR_BLOCK_SIZE}")
    block = bytes(block)
    w, x, y, z = _vector(block, table.IMU_ORIENTATION_W, table.IMU_ORIENTATION_X,
                         table.IMU_ORIENTATION_Y, table.IMU_ORIENTATION_Z)
    left_speed, right_speed = _vector(block, table.PRESENT_VELOCITY_LEFT, table.PRESENT_VELOCITY_RIGHT)
    return SensorState(
        millis=table.decode(table.MILLIS, block),
        device_status=table.decode(table.DEVICE_STATUS, block),
        buttons=tuple(bool(value) for value in _vector(block, table.BUTTON_1, table.BUTTON_2)),
        bumpers=tuple(bool(value) for value in _vector(block, table.BUMPER_1, table.BUMPER_2)),
        illumination=table.decode(table.ILLUMINATION, block),
        ir=table.decode(table.IR, block),
        sonar=table.decode(table.SONAR, block),
        battery_voltage=table.decode(table.BATTERY_VOLTAGE, block) * 0.01,
        battery_percentage=table.decode(table.BATTERY_PERCENTAGE, block) * 0.01,
        angular_velocity=_vector(block, table.IMU_ANGULAR_VELOCITY_X, table.IMU_ANGULAR_VELOCITY_Y,
                                 table.IMU_ANGULAR_VELOCITY_Z),
        linear_acceleration=_vector(block, table.IMU_LINEAR_ACCELERATION_X, table.IMU_LINEAR_ACCELERATION_Y,
                                    table.IMU_LINEAR_ACCELERATION_Z),
        magnetic_field=_vector(block, table.IMU_MAGNETIC_X, table.IMU_MAGNETIC_Y, table.IMU_MAGNETIC_Z),
        orientation=(x, y, z, w),
        present_current=_vector(block, table.PRESENT_CURRENT_LEFT, table.PRESENT_CURRENT_RIGHT),
        wheel_velocity=(left_speed * VELOCITY_UNIT_RAD_S, right_speed * VELOCITY_UNIT_RAD_S),
        encoder_ticks=_vector(block, table.PRESENT_POSITION_LEFT, table.PRESENT_POSITION_RIGHT),
        motor_connected=bool(table.decode(table.MOTOR_CONNECT, block)),
        torque_enabled=bool(table.decode(table.MOTOR_TORQUE_ENABLE, block)),
    )


class DeviceInfo(NamedTuple):
    model_number: int
    model_information: int
    firmware_version: int


DEVICE_INFO_START = table.MODEL_NUMBER_ITEM.address
DEVICE_INFO_SIZE = table.FIRMWARE_VERSION.address + table.FIRMWARE_VERSION.size - DEVICE_INFO_START


def decode_device_info(block: bytes) -> DeviceInfo:
    """Decode the EEPROM head of the table: model number, model information, firmware version."""
    block = bytes(block)
    return DeviceInfo(
        model_number=table.decode(table.MODEL_NUMBER_ITEM, block, DEVICE_INFO_START),
        model_information=table.decode(table.MODEL_INFORMATION, block, DEVICE_INFO_START),
        firmware_version=table.decode(table.FIRMWARE_VERSION, block, DEVICE_INFO_START),
    )


# The board reports the chassis it was flashed for; waffle_pi runs the waffle firmware.
EXPECTED_MODEL_INFORMATION = {
    "burger": table.MODEL_INFORMATION_BURGER,
    "waffle": table.MODEL_INFORMATION_WAFFLE,
    "waffle_pi": table.MODEL_INFORMATION_WAFFLE,
}


def check_device(info: DeviceInfo, model: str):
    """Problems with the board found at ID 200, as (fatal, warnings) message lists."""
    fatal, warnings = [], []
    if info.model_number != table.MODEL_NUMBER:
        fatal.append(
            f"the device at ID {table.DEVICE_ID} reports model number 0x{info.model_number:04X}, not the OpenCR's "
            f"0x{table.MODEL_NUMBER:04X}: flash ROBOTIS's current TurtleBot3 OpenCR firmware (see the README)")
    expected = EXPECTED_MODEL_INFORMATION.get(model)
    if expected is not None and info.model_information != expected:
        warnings.append(
            f"the OpenCR firmware is built for model information {info.model_information}, but model {model!r} "
            f"expects {expected}: the firmware's speed limits and wheel geometry may not match this robot")
    return fatal, warnings
