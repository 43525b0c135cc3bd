"""The processes the demo runs beside the snap: roscore, the simulator, the fake robot.

Each runs in its own session with its output in a log file, and is stopped with its
whole process group (roslaunch's children too).
"""
import os
import signal
import socket
import subprocess
import time
from pathlib import Path


def free_port():
    """A TCP port nobody listens on now (never roscore's default 11311)."""
    while True:
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        if port != 11311:
            return port


class Background:
    """A command in its own session, logging to `log`."""

    def __init__(self, argv, log, env):
        self.argv = [str(arg) for arg in argv]
        self.log = Path(log)
        self.log.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log, "wb") as output:
            self.process = subprocess.Popen(self.argv, stdout=output, stderr=subprocess.STDOUT, env=env,
                                            stdin=subprocess.DEVNULL, start_new_session=True)

    def running(self):
        return self.process.poll() is None

    def tail(self, lines=30):
        try:
            return "\n".join(self.log.read_text(errors="replace").splitlines()[-lines:])
        except OSError:
            return ""

    def stop(self, timeout=15.0):
        """SIGINT (roslaunch's clean shutdown), then SIGTERM, then SIGKILL, to the whole group."""
        for signum, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
            try:
                os.killpg(self.process.pid, signum)
            except ProcessLookupError:
                break
            deadline = time.monotonic() + wait
            while time.monotonic() < deadline and _group_alive(self.process.pid):
                self.process.poll()
                time.sleep(0.1)
            if not _group_alive(self.process.pid):
                break
        self.process.poll()


def _group_alive(pgid):
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    # Only zombies left (reaped by their parent later) do not count.
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] not in ("Z", "X"):
            return True
    return False


def wait_for_master(uri, timeout=60.0):
    """Until the master at `uri` answers getSystemState."""
    import xmlrpc.client
    deadline = time.monotonic() + timeout
    while True:
        try:
            code, _, _ = xmlrpc.client.ServerProxy(uri).getSystemState("/turtlebot3c_demo")
            if code == 1:
                return
        except OSError:
            pass
        if time.monotonic() > deadline:
            raise TimeoutError(f"no ROS master answered at {uri} within {timeout:.0f} s")
        time.sleep(0.2)


def roscore(port, log, env):
    return Background(["roscore", "-p", str(port)], log, env)


def simulator(world, model, log, env):
    return Background(["roslaunch", "turtlebot3c_sim", "turtlebot3_world.launch", f"world:={world}",
                       f"model:={model}"], log, env)


def fake_robot(folder, world, model, lds_model, log, env):
    """The fake OpenCR and LIDAR on ptys (links in `folder`), with the ground truth on ROS."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    process = Background(["rosrun", "turtlebot3c_sim", "fake_robot", "--opencr-link", folder / "ttyACM0",
                          "--lds-link", folder / "ttyUSB0", "--lds-model", lds_model, "--model", model,
                          "--world", world, "--publish-ground-truth"], log, env)
    return process, folder / "ttyACM0", folder / "ttyUSB0"
