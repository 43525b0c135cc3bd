"""Fill the standard ROS messages the OpenCR driver publishes from a driver Reading.

Message classes are passed in by the node, so this module imports no rospy
and the field mapping can be read (and tested) on its own.
"""
from turtlebot3c_common.message_fields import covariance
from turtlebot3c_common.se2 import yaw_to_quaternion

# Covariances as the TurtleBot3 firmware reports them (diagonals).
IMU_ORIENTATION_VARIANCE = 0.0025
IMU_ANGULAR_VELOCITY_VARIANCE = 0.02
IMU_LINEAR_ACCELERATION_VARIANCE = 0.04
MAGNETIC_FIELD_VARIANCE = 0.0048
# Wheel odometry: tight in the plane, "unknown" (huge) for what a planar robot cannot measure.
ODOM_POSE_VARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
ODOM_TWIST_VARIANCE = (1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-2)
BATTERY_DESIGN_CAPACITY = 1.8  # Ah, the TurtleBot3's LiPo
BATTERY_CELLS = 3


def fill_odometry(message, odometry, stamp, odom_frame, base_frame):
    message.header.stamp = stamp
    message.header.frame_id = odom_frame
    message.child_frame_id = base_frame
    pose = message.pose.pose
    pose.position.x, pose.position.y = odometry.pose.x, odometry.pose.y
    orientation = pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = yaw_to_quaternion(odometry.pose.yaw)
    message.pose.covariance = covariance(ODOM_POSE_VARIANCE)
    message.twist.twist.linear.x = odometry.linear
    message.twist.twist.angular.z = odometry.angular
    message.twist.covariance = covariance(ODOM_TWIST_VARIANCE)
    return message


def fill_transform(message, odometry, stamp, odom_frame, base_frame):
    message.header.stamp = stamp
    message.header.frame_id = odom_frame
    message.child_frame_id = base_frame
    message.transform.translation.x, message.transform.translation.y = odometry.pose.x, odometry.pose.y
    rotation = message.transform.rotation
    rotation.x, rotation.y, rotation.z, rotation.w = yaw_to_quaternion(odometry.pose.yaw)
    return message


def fill_joint_state(message, odometry, sensors, stamp, frame):
    message.header.stamp = stamp
    message.header.frame_id = frame
    message.name = ["wheel_left_joint", "wheel_right_joint"]
    message.position = list(odometry.wheel_positions)
    message.velocity = list(sensors.wheel_velocity)
    message.effort = []
    return message


def fill_imu(message, sensors, stamp, frame):
    message.header.stamp = stamp
    message.header.frame_id = frame
    orientation = message.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = sensors.orientation
    message.angular_velocity.x, message.angular_velocity.y, message.angular_velocity.z = sensors.angular_velocity
    acceleration = message.linear_acceleration
    acceleration.x, acceleration.y, acceleration.z = sensors.linear_acceleration
    message.orientation_covariance = covariance((IMU_ORIENTATION_VARIANCE,) * 3)
    message.angular_velocity_covariance = covariance((IMU_ANGULAR_VELOCITY_VARIANCE,) * 3)
    message.linear_acceleration_covariance = covariance((IMU_LINEAR_ACCELERATION_VARIANCE,) * 3)
    return message


def fill_magnetic_field(message, sensors, stamp, frame):
    message.header.stamp = stamp
    message.header.frame_id = frame
    field = message.magnetic_field
    field.x, field.y, field.z = sensors.magnetic_field
    message.magnetic_field_covariance = covariance((MAGNETIC_FIELD_VARIANCE,) * 3)
    return message


def fill_battery_state(message, sensors, stamp):
    """`message` is a sensor_msgs/BatteryState; constants are read from its class."""
    message.header.stamp = stamp
    message.voltage = sensors.battery_voltage
    message.percentage = min(1.0, max(0.0, sensors.battery_percentage / 100.0))
    message.design_capacity = BATTERY_DESIGN_CAPACITY
    message.present = sensors.battery_present
    message.power_supply_technology = message.POWER_SUPPLY_TECHNOLOGY_LIPO
    message.power_supply_status = message.POWER_SUPPLY_STATUS_DISCHARGING if message.present \
        else message.POWER_SUPPLY_STATUS_UNKNOWN
    message.power_supply_health = message.POWER_SUPPLY_HEALTH_UNKNOWN
    message.charge = message.capacity = message.current = float("nan")  # not measured by the board
    if hasattr(message, "temperature"):  # noetic's BatteryState has it, melodic's not
        message.temperature = float("nan")
    message.cell_voltage = [sensors.battery_voltage / BATTERY_CELLS] * BATTERY_CELLS if message.present else []
    return message


def fill_buttons(message, sensors, stamp):
    """sensor_msgs/Joy with buttons [button 1, button 2, bumper 1, bumper 2] (1 = pressed), no axes."""
    message.header.stamp = stamp
    message.axes = []
    message.buttons = [int(value) for value in sensors.buttons + sensors.bumpers]
    return message
