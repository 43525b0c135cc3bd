"""Every part of the robot judged from the facts: works (with what it shows) or not (with the one thing to do).

The parts, in the order an owner would fix them: the services, the ROS master, the
raw-usb connection, the velocity mux, the OpenCR board, its battery, the LIDAR,
odometry, the current map, navigation. A part that depends on one that failed says
so and points at it, rather than guessing.
"""
import datetime
import socket
from typing import Dict, List, NamedTuple, Optional, Tuple

from turtlebot3c_status.master_facts import MasterFacts, host_of
from turtlebot3c_status.snap_facts import Service, SnapFacts

SNAP = "turtlebot3c"
REQUIRED_SERVICES = ("roscore", "core", "teleop")
OPTIONAL_SERVICES = ("mapping", "navigation")
OK, WARN, ERROR, STALE = 0, 1, 2, 3  # diagnostic_msgs/DiagnosticStatus levels
TO_DO = "to do"  # the drivers' diagnostics carry their one thing to do under this key
RAW_USB_FIX = f"sudo snap connect {SNAP}:raw-usb"
LOCALISED_SPREAD = 0.5  # m: a pose standard deviation (x or y) above this is not localised yet
GOAL_STATES = {0: "pending", 1: "active", 2: "cancelled", 3: "reached", 4: "aborted", 5: "rejected",
               6: "cancelling", 7: "cancelling", 8: "cancelled", 9: "lost"}


class Part(NamedTuple):
    key: str  # for --json
    label: str  # for people
    ok: bool
    summary: str
    fix: str = ""  # the one thing to do when not ok
    details: Dict[str, object] = {}


class Diagnostic(NamedTuple):
    level: int
    message: str
    values: Dict[str, str]


class RosObservations(NamedTuple):
    """What the status node saw on the robot's topics during its listening window."""
    window: float  # s listened
    mux_selected: Optional[str] = None
    diagnostics: Dict[str, Diagnostic] = {}  # by status name, the latest of each
    scan_times: Tuple[float, ...] = ()  # arrival times (s)
    beams: Optional[int] = None
    odom_times: Tuple[float, ...] = ()
    pose: Optional[Tuple[float, float, float, float]] = None  # x, y, variance x, variance y (amcl_pose)
    goal: Optional[Tuple[int, str]] = None  # the latest goal's state and text; None: none seen


class CurrentMap(NamedTuple):
    name: Optional[str]  # None: no map yet
    width_m: float = 0.0
    height_m: float = 0.0
    modified: float = 0.0  # s since the epoch
    problem: str = ""


def rate(times, window: float) -> float:
    """Messages per second from their arrival times (over the window when there are too few to time)."""
    if len(times) >= 3 and times[-1] > times[0]:
        return (len(times) - 1) / (times[-1] - times[0])
    return len(times) / window if window > 0 else 0.0


def is_this_machine(host: str) -> bool:
    here = socket.gethostname()
    return host in ("localhost", here, f"{here}.local") or host.startswith("127.")


# --- the snap ---------------------------------------------------------------------------------

def services_part(snap: SnapFacts) -> Part:
    if snap.services is None:
        return Part("services", "services", False, f"cannot read them: {snap.problem}",
                    f"run this as {SNAP}.status, in the snap")
    states = snap.services
    for app in REQUIRED_SERVICES:
        state = states.get(app)
        if state is None or not state.active:
            enable = "" if state is not None and state.enabled else " --enable"
            return Part("services", "services", False, f"{app} is not running",
                        f"sudo snap start{enable} {SNAP}.{app} (why it stopped: sudo snap logs {SNAP}.{app})",
                        {app: state._asdict() if state else None for app, state in states.items()})
    running = [app for app in OPTIONAL_SERVICES if states.get(app, Service(False, False)).active]
    summary = ", ".join(REQUIRED_SERVICES) + " active"
    summary += "; " + (", ".join(running) + " active" if running else "mapping and navigation off")
    return Part("services", "services", True, summary, details={app: state._asdict() for app, state in states.items()})


def master_part(master: MasterFacts, snap: SnapFacts) -> Part:
    details = {"uri": master.uri, "answers": master.answers}
    if master.answers:
        return Part("master", "ROS master", True, f"{master.uri} answers", details=details)
    host = host_of(master.uri)
    if "does not resolve" in master.problem:
        fix = f"sudo snap set {SNAP} ros-master-host=localhost (or the master's IP address)"
    elif not is_this_machine(host):
        fix = f"start the master on {host}, or run it here: sudo snap set {SNAP} ros-master-host=localhost"
    elif snap.services is not None and not snap.services.get("roscore", Service(False, False)).active:
        fix = f"sudo snap start --enable {SNAP}.roscore"
    else:
        fix = f"sudo snap restart {SNAP}.roscore (why it fails: sudo snap logs {SNAP}.roscore)"
    return Part("master", "ROS master", False, f"no master answers at {master.uri}: {master.problem}", fix, details)


def raw_usb_part(snap: SnapFacts, simulation: bool) -> Part:
    if simulation:
        return Part("raw_usb", "raw-usb", True, "not needed (simulation=true)")
    if snap.raw_usb is None:
        return Part("raw_usb", "raw-usb", False, "not checked: snapctl did not answer", "see the services line")
    if not snap.raw_usb:
        return Part("raw_usb", "raw-usb", False, "not connected: the drivers may not open the serial ports",
                    RAW_USB_FIX)
    return Part("raw_usb", "raw-usb", True, "connected")


# --- on ROS -------------------------------------------------------------------------------------

def _unknown(key: str, label: str) -> Part:
    return Part(key, label, False, "not checked: no ROS master", "see the ROS master line")


def _service_down(snap: SnapFacts, app: str) -> bool:
    return snap.services is not None and not snap.services.get(app, Service(False, False)).active


def mux_part(ros: Optional[RosObservations], snap: SnapFacts) -> Part:
    if ros is None:
        return _unknown("mux", "mux")
    if ros.mux_selected is None:
        if _service_down(snap, "teleop"):
            return Part("mux", "mux", False, "not running", f"sudo snap start {SNAP}.teleop")
        return Part("mux", "mux", False, "says nothing on /mux/selected", f"sudo snap restart {SNAP}.teleop")
    selected = ros.mux_selected
    if selected == "__none":
        return Part("mux", "mux", True, "no input selected (the key, joy and navigation apps select theirs)",
                    details={"selected": selected})
    return Part("mux", "mux", True, f"{selected.lstrip('/')} selected", details={"selected": selected})


def _diagnostic(ros: RosObservations, prefix: str) -> Optional[Diagnostic]:
    return next((status for name, status in ros.diagnostics.items() if name.startswith(prefix)), None)


def _driver_silent(key: str, label: str, snap: SnapFacts) -> Part:
    if _service_down(snap, "core"):
        return Part(key, label, False, "not running: the core service is off", f"sudo snap start {SNAP}.core")
    return Part(key, label, False, "its driver reports nothing", f"sudo snap logs -n 50 {SNAP}.core")


def opencr_part(ros: Optional[RosObservations], snap: SnapFacts, simulation: bool) -> Part:
    if simulation:
        return Part("opencr", "OpenCR", True, "simulated (simulation=true)")
    if ros is None:
        return _unknown("opencr", "OpenCR")
    link = _diagnostic(ros, "turtlebot3c: OpenCR link")
    if link is None:
        return _driver_silent("opencr", "OpenCR", snap)
    details = dict(link.values)
    if link.level != OK:
        return Part("opencr", "OpenCR", False, link.message,
                    link.values.get(TO_DO) or f"sudo snap logs -n 50 {SNAP}.core", details)
    port = link.values.get("port", "")
    return Part("opencr", "OpenCR", True,
                f"connected on {port}, firmware version {link.values.get('firmware version', '?')}", details=details)


def battery_part(ros: Optional[RosObservations], snap: SnapFacts, simulation: bool) -> Part:
    if simulation:
        return Part("battery", "battery", True, "simulated (simulation=true)")
    if ros is None:
        return _unknown("battery", "battery")
    battery = _diagnostic(ros, "turtlebot3c: battery")
    if battery is None:
        return _driver_silent("battery", "battery", snap)
    details = dict(battery.values)
    if battery.level == STALE:
        return Part("battery", "battery", False, "no reading: the OpenCR is not connected", "see the OpenCR line",
                    details)
    voltage, percentage = battery.values.get("voltage", "?"), battery.values.get("percentage", "?")
    summary = f"{float(voltage):.1f} V ({percentage} %)" if voltage != "?" else battery.message
    if battery.level != OK:
        return Part("battery", "battery", False, battery.message,
                    battery.values.get(TO_DO, "charge the battery"), details)
    return Part("battery", "battery", True, summary, details=details)


def lidar_part(ros: Optional[RosObservations], snap: SnapFacts, simulation: bool, model: str) -> Part:
    if ros is None:
        return _unknown("lidar", "LIDAR")
    scans_per_second = rate(ros.scan_times, ros.window)
    details = {"model": "simulated" if simulation else model, "scans_per_second": round(scans_per_second, 1),
               "beams": ros.beams}
    status = None if simulation else _diagnostic(ros, "turtlebot3c: LIDAR")
    if status is not None and status.level != OK:
        details.update(status.values)
        return Part("lidar", "LIDAR", False, status.message,
                    status.values.get(TO_DO) or f"sudo snap logs -n 50 {SNAP}.core", details)
    if not ros.scan_times:
        if simulation:
            return Part("lidar", "LIDAR", False, "no scans on /scan", "start the simulator (simulation=true)",
                        details)
        if status is None:
            return _driver_silent("lidar", "LIDAR", snap)
        return Part("lidar", "LIDAR", False, f"no scans on /scan from the {model}",
                    f"sudo snap logs -n 50 {SNAP}.core", details)
    name = "simulated" if simulation else model
    return Part("lidar", "LIDAR", True, f"{name}: {scans_per_second:.1f} scans/s, {ros.beams} beams",
                details=details)


def odom_part(ros: Optional[RosObservations], simulation: bool) -> Part:
    if ros is None:
        return _unknown("odom", "/odom")
    hertz = rate(ros.odom_times, ros.window)
    if not ros.odom_times:
        fix = "start the simulator (simulation=true)" if simulation else "see the OpenCR line"
        return Part("odom", "/odom", False, "no odometry", fix, {"rate": 0.0})
    return Part("odom", "/odom", True, f"{hertz:.0f} Hz", details={"rate": round(hertz, 1)})


# --- maps and navigation ----------------------------------------------------------------------

def map_part(current: CurrentMap) -> Part:
    if current.problem:
        return Part("map", "map", False, f"{current.name}: {current.problem}", f"{SNAP}.maps list")
    if current.name is None:
        return Part("map", "map", True, f"none yet: map first (sudo snap start {SNAP}.mapping)")
    date = datetime.datetime.fromtimestamp(current.modified).strftime("%Y-%m-%d %H:%M")
    return Part("map", "map", True, f"{current.name}: {current.width_m:.1f} x {current.height_m:.1f} m, {date}",
                details=current._asdict())


def navigation_part(ros: Optional[RosObservations], snap: SnapFacts) -> Part:
    if snap.services is None or not snap.services.get("navigation", Service(False, False)).active:
        return Part("navigation", "navigation", True, f"not running (sudo snap start {SNAP}.navigation)")
    if ros is None:
        return _unknown("navigation", "navigation")
    if ros.goal is None:
        goal = "no goal yet"
    else:
        state, text = ros.goal
        goal = f"goal {GOAL_STATES.get(state, state)}" + (f" ({text})" if text and state == 4 else "")
    if ros.pose is None:
        return Part("navigation", "navigation", False, f"not localised yet; {goal}",
                    "give the robot's pose: RViz's 2D Pose Estimate")
    x, y, variance_x, variance_y = ros.pose
    spread = max(variance_x, variance_y) ** 0.5
    details = {"x": round(x, 2), "y": round(y, 2), "spread_m": round(spread, 2), "goal": goal}
    if spread > LOCALISED_SPREAD:
        return Part("navigation", "navigation", False, f"not localised (spread {spread:.1f} m); {goal}",
                    "give the robot's pose (RViz's 2D Pose Estimate), or drive a little", details)
    return Part("navigation", "navigation", True, f"localised at ({x:.2f}, {y:.2f}); {goal}", details=details)


def all_parts(snap: SnapFacts, master: MasterFacts, ros: Optional[RosObservations], current: CurrentMap) -> List[Part]:
    options = snap.options
    simulation = options.get("simulation") in (True, "true")
    model = str(options.get("lds-model") or "LDS-01")
    return [services_part(snap), master_part(master, snap), raw_usb_part(snap, simulation), mux_part(ros, snap),
            opencr_part(ros, snap, simulation), battery_part(ros, snap, simulation),
            lidar_part(ros, snap, simulation, model), odom_part(ros, simulation), map_part(current),
            navigation_part(ros, snap)]
