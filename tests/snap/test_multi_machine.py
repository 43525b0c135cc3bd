"""Two machines: the robot and a remote computer in two network namespaces joined by a veth pair.

The test creates its own hosts (root only, as here and in CI): namespaces
`tb3c-robot-N` and `tb3c-remote-N`, addresses 10.250.K.1 and .2 (a private
range, reachable only between these two namespaces), host names `tb3c-robot`
and `tb3c-remote` (their own UTS namespaces, `.local` names in
/etc/netns/<namespace>/hosts, which `ip netns exec` puts in place of /etc/hosts).
Each host has its own snapsim root with the snap installed, as two machines
would. The robot runs the snap's daemons with `ros-master-host=tb3c-robot.local`
(its roscore app runs the master) and the simulator; the remote's roscore app runs
none; the remote runs `turtlebot3c.key` in a pseudo-terminal and receives /scan and
/map as RViz would.
"""
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from testkit import ros_harness
from testkit.pty_session import PtySession
from testkit.ros_harness import Process, RosProbe, wait_until
from testkit.snap_system import REPO, SnapSystem

ODOMETRY = "nav_msgs/Odometry"
SUFFIX = str(os.getpid() % 100000)
SUBNET = f"10.250.{os.getpid() % 250 + 1}"
ROBOT_URI = "http://tb3c-robot.local:11311"


def ip(*args):
    done = subprocess.run(["ip", *args], capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"ip {' '.join(args)}: {done.stderr.strip()}")


def root_is_a_mount_point():
    """Whether `ip netns exec` can work here: it makes "/" a slave mount, which a chroot's plain folder is not."""
    return any(line.split()[4] == "/" for line in Path("/proc/self/mountinfo").read_text().splitlines())


class Host:
    """A network namespace with a host name of its own; commands run in it through `prefix`."""

    def __init__(self, role, address):
        self.hostname = f"tb3c-{role}"
        self.namespace = f"tb3c-{role}-{SUFFIX}"
        self.address = address
        self.prefix = ["ip", "netns", "exec", self.namespace, "unshare", "--uts", "sh", "-c",
                       'hostname "$0" && exec "$@"', self.hostname]


def create_hosts():
    robot, remote = Host("robot", f"{SUBNET}.1"), Host("remote", f"{SUBNET}.2")
    hosts_file = "127.0.0.1 localhost\n" + "".join(
        f"{host.address} {host.hostname} {host.hostname}.local\n" for host in (robot, remote))
    ends = {robot: f"tb3r{SUFFIX}", remote: f"tb3m{SUFFIX}"}
    ip("link", "add", ends[robot], "type", "veth", "peer", "name", ends[remote])
    try:
        for host in (robot, remote):
            ip("netns", "add", host.namespace)
            ip("link", "set", ends[host], "netns", host.namespace)
            ip("-n", host.namespace, "addr", "add", f"{host.address}/24", "dev", ends[host])
            ip("-n", host.namespace, "link", "set", ends[host], "up")
            ip("-n", host.namespace, "link", "set", "lo", "up")
            etc = Path("/etc/netns") / host.namespace
            etc.mkdir(parents=True, exist_ok=True)
            (etc / "hosts").write_text(hosts_file)
    except RuntimeError:
        # A half-made pair must not outlive the test: an end left in the
        # machine's own namespace would block the next run's pair of that name.
        for end in ends.values():
            subprocess.run(["ip", "link", "del", end], capture_output=True)
        remove_hosts((robot, remote))
        raise
    return robot, remote


def remove_hosts(hosts):
    for host in hosts:
        done = subprocess.run(["ip", "netns", "pids", host.namespace], capture_output=True, text=True)
        for pid in done.stdout.split():
            ros_harness.kill_quietly(int(pid), 9)
        subprocess.run(["ip", "netns", "del", host.namespace], capture_output=True)
        shutil.rmtree(Path("/etc/netns") / host.namespace, ignore_errors=True)


class HostSnapSystem(SnapSystem):
    """A snapsim root on one of the test hosts: snapsim runs inside its namespace."""

    def __init__(self, host, root, build_dir):
        super().__init__(root, build_dir=build_dir)
        self.host = host
        self.snapsim_program = host.prefix + self.snapsim_program


class RemoteGraph:
    """What a probe needs to join the robot's ROS graph from a host: environment, work folder, prefix."""

    def __init__(self, host, ros_env, workdir):
        self.command_prefix = host.prefix
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.env = dict(ros_env, ROS_MASTER_URI=ROBOT_URI, ROS_HOSTNAME=f"{host.hostname}.local",
                        ROS_HOME=str(self.workdir / "ros_home"), ROS_LOG_DIR=str(self.workdir / "ros_log"))


@pytest.fixture(scope="module")
def machines(ros_env, tmp_path_factory):
    if os.geteuid() != 0:
        pytest.fail("the multi-machine tests create network namespaces: run them as root (CI does)")
    if not root_is_a_mount_point():
        pytest.skip("this is a chroot whose / is not a mount point: `ip netns exec` cannot enter a namespace here")
    folder = tmp_path_factory.mktemp("machines")
    hosts = create_hosts()
    robot_host, remote_host = hosts
    systems, processes, probes = [], [], []
    try:
        robot = HostSnapSystem(robot_host, folder / "robot", ros_harness.BUILD)
        systems.append(robot)
        robot.snapsim("install", REPO, "--dangerous")
        assert robot.config("turtlebot3c")["ros-master-host"] == "tb3c-robot.local"
        robot.snapsim("set", "turtlebot3c", "simulation=true")
        remote = HostSnapSystem(remote_host, folder / "remote", ros_harness.BUILD)
        systems.append(remote)
        remote.snapsim("install", REPO, "--dangerous")
        remote.snapsim("stop", "--disable", "turtlebot3c.core", "turtlebot3c.teleop")  # a laptop, not a robot
        remote.snapsim("set", "turtlebot3c", "ros-master-host=tb3c-robot.local")

        on_robot = RemoteGraph(robot_host, ros_env, folder / "robot-graph")
        simulator = Process(robot_host.prefix + ["roslaunch", "--wait", "turtlebot3c_sim", "turtlebot3_world.launch",
                                                 "model:=waffle_pi"],
                            on_robot.env, folder / "simulator.log", name="simulator")
        processes.append(simulator)
        robot.snapsim("start", "turtlebot3c.mapping")
        remote_graph = RemoteGraph(remote_host, ros_env, folder / "remote-graph")
        probe = RosProbe(remote_graph)
        probes.append(probe)
        yield robot, remote, probe, simulator
    finally:
        for probe in probes:
            probe.close()
        for process in processes:
            process.stop()
        for system in systems:
            system.shutdown()
        remove_hosts(hosts)


def test_the_remote_receives_scans_and_the_map_from_the_robot(machines):
    _, _, probe, _ = machines
    scan = probe.wait_for_message("/scan", "sensor_msgs/LaserScan", timeout=120)
    assert len(scan["ranges"]) == 360
    grid = probe.wait_for_message("/map", "nav_msgs/OccupancyGrid", start=0, timeout=120)
    assert grid["info"]["width"] > 0 and any(value == 100 for value in grid["data"])


def test_the_key_app_on_the_remote_drives_the_robot(machines):
    _, remote, probe, _ = machines
    probe.subscribe("/odom", ODOMETRY)
    start = probe.wait_for_message("/odom", ODOMETRY, timeout=60)["pose"]["pose"]["position"]
    session = PtySession(remote.env, remote.command("run", "turtlebot3c.key"))
    try:
        wait_until(session.in_key_mode, 120, lambda: f"the key app never took the terminal:\n{session.text()}")
        assert "velocity input is now 'key_vel'" in session.text()
        session.type("www")

        def travelled():
            position = probe.messages("/odom")[-1]["pose"]["pose"]["position"]
            return ((position["x"] - start["x"]) ** 2 + (position["y"] - start["y"]) ** 2) ** 0.5 > 0.05
        wait_until(travelled, 30, lambda: f"the robot did not move:\n{session.text()}")
        session.type(" ")
        session.type("\x03")
        assert session.wait_exit(30) == 0
        assert session.attributes() == session.original
    finally:
        session.close()


def test_a_wrong_ros_master_host_fails_clearly_instead_of_hanging(machines):
    _, remote, _, _ = machines
    nobody = f"{SUBNET}.77"  # in the test network, where no machine answers
    remote.snapsim("set", "turtlebot3c", f"ros-master-host={nobody}")
    session = PtySession(dict(remote.env, MUX_SELECT_TIMEOUT="5"), remote.command("run", "turtlebot3c.key"))
    try:
        started = time.monotonic()
        assert session.wait_exit(90) != 0
        text = session.text()
        assert f"no ROS master answers at http://{nobody}:11311" in text, text
        assert "ros-master-host" in text
        print(f"wrong ros-master-host reported after {time.monotonic() - started:.1f} s")
    finally:
        session.close()
        remote.snapsim("set", "turtlebot3c", "ros-master-host=tb3c-robot.local")


def robot_master_pid(robot_host):
    done = subprocess.run(["ip", "netns", "pids", robot_host.namespace], capture_output=True, text=True)
    for pid in done.stdout.split():
        try:
            words = open(f"/proc/{pid}/cmdline", "rb").read().split(b"\0")
        except OSError:
            continue
        if any(word.endswith(b"/rosmaster") for word in words):
            return int(pid)
    return None


def test_a_killed_master_on_the_robot_comes_back_with_every_daemon_node(machines, ros_env, tmp_path):
    """The roscore app starts it again at once: the daemons' nodes register with it, none restarts."""
    robot, _, _, _ = machines
    master = robot_master_pid(robot.host)
    assert master, "no rosmaster runs on the robot"
    restarts = {app: robot.status("turtlebot3c", app)["main_pid"] for app in ("core", "teleop")}
    ros_harness.kill_quietly(master, 9)
    wait_until(lambda: robot_master_pid(robot.host) not in (None, master), 90,
               lambda: f"no new master on the robot:\n{robot.logs('turtlebot3c')}")
    probe = RosProbe(RemoteGraph(robot.host, ros_env, tmp_path / "after-restart"))
    try:
        # A fresh subscriber finds the daemons' nodes again: they registered with the new master.
        probe.wait_for_message("/mux/selected", "std_msgs/String", start=0, timeout=90)
        probe.wait_for_message("/tf_static", "tf2_msgs/TFMessage", start=0, timeout=90)
        probe.call("/mux/select", {"topic": "key_vel"}, timeout=30)
    finally:
        probe.close()
    statuses = {app: robot.status("turtlebot3c", app) for app in restarts}
    assert all(status["state"] == "active" for status in statuses.values()), statuses
    # The roscore app started the master again; core and teleop were not restarted.
    assert {app: status["main_pid"] for app, status in statuses.items()} == restarts
    assert "roscore: the ROS master at http://tb3c-robot.local:11311 ended" in robot.logs("turtlebot3c.roscore")


def test_the_remote_runs_no_master_and_says_so(machines):
    robot, remote, _, _ = machines
    wait_until(lambda: "no master runs here" in remote.logs("turtlebot3c.roscore"), 30,
               lambda: remote.logs("turtlebot3c.roscore"))
    assert "roscore: ros-master-host now names another machine (http://tb3c-robot.local:11311)" in \
        remote.logs("turtlebot3c.roscore")
    assert robot_master_pid(remote.host) is None
    assert robot_master_pid(robot.host) is not None
