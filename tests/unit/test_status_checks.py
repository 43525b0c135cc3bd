"""turtlebot3c.status's judgement of each part, from facts made up here (no snapd, no ROS)."""
import json

from turtlebot3c_status import checks, report
from turtlebot3c_status.checks import Diagnostic, RosObservations
from turtlebot3c_status.master_facts import MasterFacts, ask_master
from turtlebot3c_status.snap_facts import Service, SnapFacts, parse_services

ALL_ACTIVE = {app: Service(True, True) for app in ("roscore", "core", "teleop")}
ALL_ACTIVE.update(mapping=Service(False, False), navigation=Service(False, False))
OPTIONS = {"simulation": False, "lds-model": "LDS-01", "ros-master-host": "localhost"}
SNAP = SnapFacts(ALL_ACTIVE, True, OPTIONS)
MASTER = MasterFacts("http://localhost:11311", True)
HEALTHY_DIAGNOSTICS = {
    "turtlebot3c: OpenCR link": Diagnostic(0, "connected", {"port": "/dev/ttyACM0", "firmware version": "5"}),
    "turtlebot3c: battery": Diagnostic(0, "12.0 V", {"voltage": "12.00", "percentage": "83"}),
    "turtlebot3c: LIDAR (LDS-01)": Diagnostic(0, "reading /dev/ttyUSB0", {}),
}
HEALTHY = RosObservations(2.0, "nav_vel", HEALTHY_DIAGNOSTICS, tuple(0.2 * i for i in range(10)), 360,
                          tuple(0.02 * i for i in range(100)))
NO_MAP = checks.CurrentMap(None)


def parts_by_key(snap=SNAP, master=MASTER, ros=HEALTHY, current=NO_MAP):
    return {part.key: part for part in checks.all_parts(snap, master, ros, current)}


def test_a_healthy_robot_is_all_well_and_exits_0():
    parts = checks.all_parts(SNAP, MASTER, HEALTHY, NO_MAP)
    assert all(part.ok for part in parts), report.text(parts)
    assert report.exit_status(parts) == 0
    lines = report.text(parts).splitlines()
    assert [line.split()[1] for line in lines] == ["services", "ROS", "raw-usb", "mux", "OpenCR", "battery",
                                                   "LIDAR", "/odom", "map", "navigation"]
    assert lines[6].endswith("LDS-01: 5.0 scans/s, 360 beams")
    assert "nav_vel selected" in lines[3] and "12.0 V (83 %)" in lines[5]


def test_json_has_every_part_and_the_overall_verdict():
    document = json.loads(report.as_json(checks.all_parts(SNAP, MASTER, HEALTHY, NO_MAP)))
    assert document["ok"] is True
    assert [part["part"] for part in document["parts"]] == ["services", "master", "raw_usb", "mux", "opencr",
                                                           "battery", "lidar", "odom", "map", "navigation"]


def test_a_stopped_service_names_the_snap_start_that_fixes_it():
    services = dict(ALL_ACTIVE, core=Service(False, False))
    part = parts_by_key(snap=SNAP._replace(services=services))["services"]
    assert not part.ok and part.fix.startswith("sudo snap start --enable turtlebot3c.core")


def test_no_master_marks_what_depends_on_it_and_points_at_the_master_line():
    master = MasterFacts("http://localhost:11311", False, "nothing listens there")
    parts = parts_by_key(master=master, ros=None)
    assert not parts["master"].ok and "turtlebot3c.roscore" in parts["master"].fix
    for key in ("mux", "opencr", "battery", "lidar", "odom"):
        assert not parts[key].ok and parts[key].fix == "see the ROS master line"


def test_a_master_name_that_does_not_resolve_points_at_ros_master_host():
    master = MasterFacts("http://robot.local:11311", False, "its host robot.local does not resolve")
    assert "ros-master-host=localhost" in parts_by_key(master=master, ros=None)["master"].fix


def test_raw_usb_not_connected_says_the_snap_connect():
    part = parts_by_key(snap=SNAP._replace(raw_usb=False))["raw_usb"]
    assert not part.ok and part.fix == "sudo snap connect turtlebot3c:raw-usb"
    simulated = SNAP._replace(raw_usb=False, options=dict(OPTIONS, simulation=True))
    assert parts_by_key(snap=simulated)["raw_usb"].ok


def test_the_drivers_one_thing_to_do_is_shown():
    diagnostics = dict(HEALTHY_DIAGNOSTICS)
    diagnostics["turtlebot3c: OpenCR link"] = Diagnostic(2, "not connected to /dev/ttyACM0: the OpenCR runs X",
                                                         {"to do": "flash it"})
    diagnostics["turtlebot3c: LIDAR (LDS-01)"] = Diagnostic(
        2, "no scans: the LIDAR on /dev/ttyUSB0 streams LDS-02 packets, but lds-model is LDS-01",
        {"to do": "sudo snap set turtlebot3c lds-model=LDS-02"})
    parts = parts_by_key(ros=HEALTHY._replace(diagnostics=diagnostics, scan_times=()))
    assert (parts["opencr"].ok, parts["opencr"].fix) == (False, "flash it")
    assert (parts["lidar"].ok, parts["lidar"].fix) == (False, "sudo snap set turtlebot3c lds-model=LDS-02")
    line = report.text(list(parts.values())).splitlines()[6]
    assert line.startswith("\u2718 LIDAR") and line.endswith("-> sudo snap set turtlebot3c lds-model=LDS-02")


def test_a_low_battery_is_not_all_well():
    diagnostics = dict(HEALTHY_DIAGNOSTICS)
    diagnostics["turtlebot3c: battery"] = Diagnostic(1, "11.3 V, low: the motors stop below 11.0 V",
                                                     {"voltage": "11.30", "to do": "charge the battery soon"})
    parts = checks.all_parts(SNAP, MASTER, HEALTHY._replace(diagnostics=diagnostics), NO_MAP)
    battery = next(part for part in parts if part.key == "battery")
    assert not battery.ok and battery.fix == "charge the battery soon"
    assert report.exit_status(parts) == 1


def test_navigation_running_but_not_localised_says_how_to_give_the_pose():
    snap = SNAP._replace(services=dict(ALL_ACTIVE, navigation=Service(True, True)))
    lost = parts_by_key(snap=snap, ros=HEALTHY._replace(pose=(1.0, 2.0, 4.0, 4.0)))["navigation"]
    assert not lost.ok and "2D Pose Estimate" in lost.fix
    found = parts_by_key(snap=snap, ros=HEALTHY._replace(pose=(1.0, 2.0, 0.01, 0.01), goal=(3, "")))["navigation"]
    assert found.ok and found.summary == "localised at (1.00, 2.00); goal reached"


def test_the_current_map_is_named_with_its_size():
    current = checks.CurrentMap("kitchen", 4.0, 3.5, 0.0)
    assert parts_by_key(current=current)["map"].summary.startswith("kitchen: 4.0 x 3.5 m, ")


def test_snapctl_services_output_is_parsed():
    text = ("Service                 Startup   Current   Notes\n"
            "turtlebot3c.core        enabled   active    -\n"
            "turtlebot3c.mapping     disabled  inactive  -\n")
    assert parse_services(text) == {"core": Service(True, True), "mapping": Service(False, False)}


def test_a_master_that_is_not_there_is_told_quickly():
    facts = ask_master("http://127.0.0.1:9/", timeout=1.0)  # the discard port: nothing listens
    assert not facts.answers and facts.problem
