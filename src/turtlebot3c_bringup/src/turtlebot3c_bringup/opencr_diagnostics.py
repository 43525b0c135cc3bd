"""What the OpenCR driver reports on /diagnostics, as plain tuples the node turns into messages."""
from typing import Dict, List, NamedTuple

OK, WARN, ERROR, STALE = 0, 1, 2, 3  # diagnostic_msgs/DiagnosticStatus levels
# ROBOTIS's ROS 2 OpenCR firmware switches the DYNAMIXELs' power off when its 1 s average of the
# battery voltage stays below 11.0 V for 5 s (turtlebot3_diagnosis.cpp, updateVoltageCheck), and on
# again above it: below this the motors stop, whatever the driver commands.
FIRMWARE_CUTOFF_VOLTAGE = 11.0  # V
LOW_BATTERY_VOLTAGE = 11.5  # V; warn while there is still time to charge before the cut-off
TO_DO = "to do"  # the key of a status's one thing to do, which turtlebot3c.status shows


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
        if driver.other_firmware is not None:
            values["firmware found"] = driver.other_firmware.describe()
        if driver.fix:
            values[TO_DO] = driver.fix
        problem = driver.problem or stats.last_error
        message = problem if port in problem else f"not connected to {port}: {problem}"  # the port once
        return Status(ERROR, "turtlebot3c: OpenCR link", message, values)
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
    battery = battery_status(sensors)
    sensor_values = {
        "button 1": str(int(sensors.buttons[0])), "button 2": str(int(sensors.buttons[1])),
        "bumper 1": str(int(sensors.bumpers[0])), "bumper 2": str(int(sensors.bumpers[1])),
        "illumination": str(sensors.illumination), "ir": str(sensors.ir), "sonar": f"{sensors.sonar:.3f}",
        "board time (ms)": str(sensors.millis),
    }
    return [motors, battery, Status(OK, "turtlebot3c: sensors", "ok", sensor_values)]


def battery_status(sensors) -> Status:
    voltage = sensors.battery_voltage
    values = {"voltage": f"{voltage:.2f}", "percentage": f"{sensors.battery_percentage:.0f}"}
    name = "turtlebot3c: battery"
    if not sensors.battery_present:
        values[TO_DO] = "connect and switch on the battery: the motors do not run from USB power"
        return Status(WARN, name, "no battery: running from USB power", values)
    if voltage < FIRMWARE_CUTOFF_VOLTAGE:
        values[TO_DO] = "charge or swap the battery now"
        return Status(ERROR, name, f"{voltage:.1f} V, below the firmware's {FIRMWARE_CUTOFF_VOLTAGE:.1f} V cut-off: "
                                   "the motors will stop", values)
    if voltage < LOW_BATTERY_VOLTAGE:
        values[TO_DO] = "charge the battery soon"
        return Status(WARN, name, f"{voltage:.1f} V, low: the motors stop below {FIRMWARE_CUTOFF_VOLTAGE:.1f} V",
                      values)
    return Status(OK, name, f"{voltage:.1f} V", values)
