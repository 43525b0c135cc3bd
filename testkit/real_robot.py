"""The fake robot brought up through turtlebot3c_bringup.launch, and helpers to drive and inspect it.

Shared by the bringup tests, the fault tests and benchmarks/bench_faults.
"""
import signal
import time
import xmlrpc.client

import pytest

from testkit.ros_harness import wait_until
from turtlebot3c_sim.fake_robot import send_command

ODOMETRY = "nav_msgs/Odometry"
SCAN = "sensor_msgs/LaserScan"
TWIST = "geometry_msgs/Twist"


def start_robot(master, model, lds_model, world="turtlebot3_world"):
    devices = master.workdir / f"dev-{lds_model}"
    devices.mkdir(exist_ok=True)
    control = devices / "control"
    fake = master.rosrun("turtlebot3c_sim", "fake_robot", "--opencr-link", devices / "ttyACM0",
                         "--lds-link", devices / "ttyUSB0", "--lds-model", lds_model, "--model", model,
                         "--world", world, "--noise", "none", "--control-socket", control)
    wait_until(lambda: control.exists() or not fake.running(), 30, "the fake robot never came up")
    assert fake.running(), fake.log_text()
    master.launch("turtlebot3c_bringup", "turtlebot3c_bringup.launch", "simulation:=false", f"model:={model}",
                  f"lds_model:={lds_model}", f"opencr_port:={devices / 'ttyACM0'}",
                  f"lds_port:={devices / 'ttyUSB0'}")
    return control


def drive(probe, linear, angular, seconds):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        probe.publish("/cmd_vel", TWIST, {"linear": {"x": linear}, "angular": {"z": angular}})
        time.sleep(0.1)


def latest_odometry(probe):
    return probe.wait_for_message("/odom", ODOMETRY)["pose"]["pose"]


def node_pid(master, name):
    code, _, uri = master.master_api().lookupNode("/test", name)
    if code != 1:
        return None
    try:
        return xmlrpc.client.ServerProxy(uri).getPid("/test")[2]
    except OSError:
        return None


# --- driving the fake robot and watching it stop: the fault tests and benchmarks/bench_faults

SPEED = 0.15
CHAIN_NODES = ("/turtlebot3_core", "/mux", "/velocity_watchdog")
DAEMON_NODES = ("/robot_state_publisher", "/turtlebot3_core", "/turtlebot3_lds", "/mux", "/velocity_watchdog")


def status(control):
    return send_command(control, "status")


class KeySource:
    """A `key_vel` source like the key app: 10 Hz, selected on the mux; kill() is a SIGKILL."""

    def __init__(self, master, linear=SPEED):
        master.probe.call("/mux/select", {"topic": "key_vel"})
        self.process = master.start(["rostopic", "pub", "-r", "10", "/key_vel", TWIST, f"{{linear: {{x: {linear}}}}}"],
                                    name="key_vel_source")

    def kill(self):
        self.process.signal(signal.SIGKILL)
        self.process.wait(10)


def wait_until_driving(control, speed=SPEED, timeout=30):
    wait_until(lambda: status(control)["velocity"][0] == pytest.approx(speed), timeout,
               lambda: f"the robot never reached {speed} m/s: {status(control)}")


def watch_until_at_rest(control, since=None, timeout=5.0):
    """Simulated times at which the command became zero and the robot came to rest, from `since`
    (the simulated time just before the fault; default: now)."""
    start = status(control)["time"] if since is None else since
    samples = []

    def at_rest():
        samples.append(status(control))
        return samples[-1]["velocity"] == [0.0, 0.0]
    wait_until(at_rest, timeout, lambda: f"the robot kept moving: {samples[-1]}", interval=0.01)
    # The board's own record of when the command became zero: a poll on a loaded machine comes later.
    zero_command = max(next(s["command_since"] for s in samples if s["command"] == [0.0, 0.0]), start)
    return zero_command - start, samples[-1]["time"] - start
