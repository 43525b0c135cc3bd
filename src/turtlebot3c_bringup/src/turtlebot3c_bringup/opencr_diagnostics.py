"""What the OpenCR driver reports on /diagnostics, as plain tuples the node turns into messages."""
from typing import Dict, List, NamedTuple

OK, WARN, ERROR, STALE = 0, 1, 2, 3  # diagnostic_msgs/DiagnosticStatus levels
LOW_BATTERY_VOLTAGE = 11.0  # V; a 3-cell LiPo is nearly empty here


class Status(NamedTuple):
    level: int
    name: str
    message: str
    values: Dict[str, str]


def link_status(driver, port: str, baud: int) -> Status:
    stats = driver.stats
    values = {
        "port": port, "baud rate": str(baud), "connected": str(driver.connected),
        "reads": str(stats.reads), "writes": str(stats.writes),
        "communication errors": str(stats.total_errors),
        "link losses": str(stats.link_losses), "reconnections": str(stats.reconnections),
        "odometry discontinuities skipped": str(driver.odometry.discontinuities),
        "last error": stats.last_error,
    }
    values.update({f"errors: {kind}": str(count) for kind, count in sorted(stats.errors.items())})
    if driver.device_info is not None:
        values["firmware version"] = str(driver.device_info.firmware_version)
        values["model information"] = str(driver.device_info.model_information)
    if not driver.connected:
        return Status(ERROR, "turtlebot3c: OpenCR link", f"not connected to {port}: {stats.last_error}", values)
    return Status(OK, "turtlebot3c: OpenCR link", "connected", values)


def sensor_statuses(sensors) -> List[Status]:
    if sensors is None:
        return [Status(STALE, name, "no reading from the OpenCR yet", {})
                for name in ("turtlebot3c: motors", "turtlebot3c: battery", "turtlebot3c: sensors")]
    if sensors.device_status != 0:
        motors = Status(ERROR, "turtlebot3c: motors", "Dynamixels not connected: check their cables and power", {})
    elif not sensors.torque_enabled:
        motors = Status(WARN, "turtlebot3c: motors", "torque off", {})
    else:
        motors = Status(OK, "turtlebot3c: motors", "torque on", {})
    motors.values.update({"left encoder": str(sensors.encoder_ticks[0]),
                          "right encoder": str(sensors.encoder_ticks[1]),
                          "left current": str(sensors.present_current[0]),
                          "right current": str(sensors.present_current[1])})
    battery_values = {"voltage": f"{sensors.battery_voltage:.2f}", "percentage": f"{sensors.battery_percentage:.0f}"}
    if not sensors.battery_present:
        battery = Status(WARN, "turtlebot3c: battery", "no battery: running from USB power", battery_values)
    elif sensors.battery_voltage <= LOW_BATTERY_VOLTAGE:
        battery = Status(WARN, "turtlebot3c: battery", "low battery: charge it", battery_values)
    else:
        battery = Status(OK, "turtlebot3c: battery", "ok", battery_values)
    sensor_values = {
        "button 1": str(int(sensors.buttons[0])), "button 2": str(int(sensors.buttons[1])),
        "bumper 1": str(int(sensors.bumpers[0])), "bumper 2": str(int(sensors.bumpers[1])),
        "illumination": str(sensors.illumination), "ir": str(sensors.ir), "sonar": f"{sensors.sonar:.3f}",
        "board time (ms)": str(sensors.millis),
    }
    return [motors, battery, Status(OK, "turtlebot3c: sensors", "ok", sensor_values)]
