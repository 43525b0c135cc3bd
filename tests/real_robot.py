"""The fake robot brought up through turtlebot3c_bringup.launch, and helpers to drive and inspect it.

Shared by the bringup tests and the fault tests.
"""
import time
import xmlrpc.client

from ros_harness import wait_until

ODOMETRY = "nav_msgs/Odometry"
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
