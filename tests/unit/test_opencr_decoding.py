"""OpenCR sensor block decoding, odometry from encoder ticks, and velocity commands."""
import math
import struct

import pytest

from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_bringup.opencr_sensors import DeviceInfo, check_device, decode_device_info, decode_sensor_block
from turtlebot3c_bringup.velocity_command import clamp_to_model, command_bytes
from turtlebot3c_bringup.wheel_odometry import WheelOdometry, tick_delta
from turtlebot3c_description.models import get_model


def sensor_block(**values):
    """A sensor block with the given control-table items set (names as in opencr_control_table)."""
    block = bytearray(table.SENSOR_BLOCK_SIZE)
    for name, value in values.items():
        item = getattr(table, name)
        struct.pack_into(item.format, block, item.address - table.SENSOR_BLOCK_START, value)
    return bytes(block)


def test_sensor_block_values_are_converted_to_si_units():
    block = sensor_block(BATTERY_VOLTAGE=1185, BATTERY_PERCENTAGE=7500, BUTTON_2=1, BUMPER_1=1,
                         PRESENT_POSITION_LEFT=-4096, PRESENT_POSITION_RIGHT=123456,
                         PRESENT_VELOCITY_LEFT=100, IMU_ANGULAR_VELOCITY_Z=0.5, IMU_LINEAR_ACCELERATION_Z=9.81,
                         IMU_ORIENTATION_W=1.0, MOTOR_TORQUE_ENABLE=1, DEVICE_STATUS=-1, MILLIS=4242)
    state = decode_sensor_block(block)
    assert state.battery_voltage == pytest.approx(11.85)
    assert state.battery_percentage == pytest.approx(75.0)
    assert state.battery_present
    assert state.buttons == (False, True) and state.bumpers == (True, False)
    assert state.encoder_ticks == (-4096, 123456)
    assert state.wheel_velocity[0] == pytest.approx(100 * 0.229 * 2 * math.pi / 60)
    assert state.angular_velocity[2] == pytest.approx(0.5)
    assert state.linear_acceleration[2] == pytest.approx(9.81, rel=1e-6)
    assert state.orientation == (0.0, 0.0, 0.0, 1.0)
    assert state.torque_enabled and state.device_status == -1 and state.millis == 4242


def test_sensor_block_of_the_wrong_size_is_refused_with_the_sizes():
    with pytest.raises(ValueError, match="171 bytes, expected 172"):
        decode_sensor_block(bytes(171))


def test_imu_yaw_comes_from_the_quaternion_and_is_none_without_a_valid_one():
    yaw = 0.7
    state = decode_sensor_block(sensor_block(IMU_ORIENTATION_W=math.cos(yaw / 2), IMU_ORIENTATION_Z=math.sin(yaw / 2)))
    assert state.imu_yaw == pytest.approx(yaw, abs=1e-6)
    assert decode_sensor_block(sensor_block()).imu_yaw is None


def test_device_info_and_checks():
    head = struct.pack("<HIB", table.MODEL_NUMBER, table.MODEL_INFORMATION_WAFFLE, 5)
    info = decode_device_info(head)
    assert info == DeviceInfo(table.MODEL_NUMBER, 2, 5)
    assert check_device(info, "waffle_pi") == ([], [])
    fatal, warnings = check_device(info, "burger")
    assert fatal == [] and "model information 2" in warnings[0]
    fatal, _ = check_device(DeviceInfo(1060, 2, 5), "waffle")
    assert "0x0424" in fatal[0] and "0x5000" in fatal[0]


def test_tick_delta_crosses_the_int32_wrap():
    assert tick_delta(-2**31 + 5, 2**31 - 5) == 10
    assert tick_delta(2**31 - 5, -2**31 + 5) == -10
    assert tick_delta(100, 40) == 60


def burger_odometry(use_imu_yaw=False):
    model = get_model("burger")
    return WheelOdometry(model.wheel_radius, model.wheel_separation, model.max_linear_velocity / model.wheel_radius,
                         use_imu_yaw=use_imu_yaw)


def ticks_for(distance):
    return int(round(distance / 0.033 / table.TICK_TO_RAD))


def distance_of(ticks):
    return ticks * table.TICK_TO_RAD * 0.033


def test_first_reading_is_only_a_baseline():
    odometry = burger_odometry()
    assert not odometry.update(1000, 2000, stamp=1.0)
    assert odometry.pose == (0.0, 0.0, 0.0)


def test_straight_line_from_equal_wheel_ticks():
    odometry = burger_odometry()
    odometry.update(0, 0, 0.0)
    step = ticks_for(0.01)
    for i in range(1, 21):
        assert odometry.update(i * step, i * step, i * 0.05)
    assert odometry.pose.x == pytest.approx(distance_of(20 * step))
    assert odometry.pose.y == pytest.approx(0.0, abs=1e-9)
    assert odometry.linear == pytest.approx(distance_of(step) / 0.05)
    assert odometry.wheel_positions[0] == pytest.approx(20 * step * table.TICK_TO_RAD)


def test_spin_in_place_turns_by_wheel_difference_over_separation():
    odometry = burger_odometry()
    odometry.update(0, 0, 0.0)
    # each wheel travels a quarter of the circle of diameter separation => 90 degrees
    quarter = math.pi * 0.160 / 4
    steps = 20
    for i in range(1, steps + 1):
        travelled = ticks_for(quarter * i / steps)
        odometry.update(-travelled, travelled, i * 0.05)
    assert odometry.pose.yaw == pytest.approx(math.pi / 2, abs=2e-3)
    assert math.hypot(odometry.pose.x, odometry.pose.y) == pytest.approx(0.0, abs=1e-9)


def test_arc_with_midpoint_integration_matches_the_closed_form():
    odometry = burger_odometry()
    odometry.update(0, 0, 0.0)
    radius, angle, steps = 0.5, math.pi / 2, 200
    left_total, right_total = angle * (radius - 0.08), angle * (radius + 0.08)
    for i in range(1, steps + 1):
        odometry.update(ticks_for(left_total * i / steps), ticks_for(right_total * i / steps), i * 0.02)
    assert odometry.pose.x == pytest.approx(radius, abs=2e-3)
    assert odometry.pose.y == pytest.approx(radius, abs=2e-3)
    assert odometry.pose.yaw == pytest.approx(angle, abs=2e-3)


def test_imu_heading_is_used_when_enabled():
    odometry = burger_odometry(use_imu_yaw=True)
    odometry.update(0, 0, 0.0, imu_yaw=0.0)
    odometry.update(ticks_for(0.01), ticks_for(0.01), 0.05, imu_yaw=0.2)
    assert odometry.pose.yaw == pytest.approx(0.2)
    assert odometry.pose.y == pytest.approx(distance_of(ticks_for(0.01)) * math.sin(0.1))


def test_encoder_jump_after_a_board_reset_is_skipped_not_integrated():
    odometry = burger_odometry()
    odometry.update(50000, 50000, 0.0)
    odometry.update(50000 + ticks_for(0.01), 50000 + ticks_for(0.01), 0.05)
    before = odometry.pose
    assert not odometry.update(0, 0, 0.10)  # the board restarted its counters
    assert odometry.pose == before and odometry.discontinuities == 1
    assert odometry.update(ticks_for(0.01), ticks_for(0.01), 0.15)
    assert odometry.pose.x == pytest.approx(before.x + distance_of(ticks_for(0.01)))


def test_rebaseline_after_reconnect_keeps_the_pose():
    odometry = burger_odometry()
    odometry.update(0, 0, 0.0)
    odometry.update(ticks_for(0.01), ticks_for(0.01), 0.05)
    pose = odometry.pose
    odometry.rebaseline()
    assert not odometry.update(777, 777, 5.0)
    assert odometry.pose == pose


@pytest.mark.parametrize("model_name", ["burger", "waffle", "waffle_pi"])
def test_commands_are_clamped_to_the_model_limits(model_name):
    model = get_model(model_name)
    linear, angular = clamp_to_model(model, 10.0, -10.0)
    assert (linear, angular) == (model.max_linear_velocity, -model.max_angular_velocity)
    words = struct.unpack("<6i", command_bytes(model, 10.0, -10.0))
    assert words[1:5] == (0, 0, 0, 0)
    assert words[0] / 100 <= model.max_linear_velocity
    assert -words[5] / 100 <= model.max_angular_velocity
    assert clamp_to_model(model, float("nan"), 0.1) == (0.0, 0.1)


def test_velocity_command_layout_is_six_int32_in_hundredths():
    assert struct.unpack("<6i", table.encode_velocity_command(0.29, -1.5)) == (29, 0, 0, 0, 0, -150)
    assert len(table.encode_velocity_command(0.0, 0.0)) == table.CMD_VELOCITY_SIZE
