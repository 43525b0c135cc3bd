"""Helpers for the snap tests: a snapsim system under a temporary root."""
import json
import os
import shutil
import signal
import subprocess
import time
import xmlrpc.client
from pathlib import Path

from snapsim.supervisor import root_processes
from testkit import ros_harness
from testkit.ros_harness import wait_until

REPO = ros_harness.REPO
SNAPSIM = ros_harness.VENV / "bin" / "snapsim"  # installed by tools/setup-env
def user_environment(**extra):
    """A plain user's shell environment: no ROS workspace sourced."""
    env = {
        "PATH": f"{ros_harness.VENV / 'bin'}:/usr/local/bin:/usr/bin:/bin",
        "LANG": "C.UTF-8",
        "HOME": os.environ.get("HOME", "/root"),
        ros_harness.RUN_MARKER: ros_harness.RUN_ID,
        "SNAPSIM_PASSENV": ros_harness.RUN_MARKER,
    }
    env.update({key: str(value) for key, value in extra.items()})
    return env


class SnapSystem:
    """A snapsim system under `root`, driven through snapsim like a user drives `snap`."""

    def __init__(self, root, build_dir=None, etc_environment=None):
        self.root = Path(root)
        (self.root / "etc").mkdir(parents=True, exist_ok=True)
        if etc_environment:
            (self.root / "etc" / "environment").write_text(
                "".join(f"{key}={value}\n" for key, value in etc_environment.items()))
        self.env = user_environment()
        self.snapsim_program = [str(SNAPSIM)]  # or another interpreter's `python3 -m snapsim`
        if build_dir is not None:
            self.env["TURTLEBOT3C_BUILD_DIR"] = str(build_dir)

    def command(self, *args):
        """The command line that runs `snap ARGS` on this system."""
        return self.snapsim_program + ["--root", str(self.root)] + [str(arg) for arg in args]

    def snapsim(self, *args, check=True, env=None, timeout=240, input=None):
        done = subprocess.run(self.command(*args),
                              env=dict(self.env, **(env or {})), capture_output=True, text=True,
                              timeout=timeout, input=input)
        if check and done.returncode != 0:
            raise AssertionError(f"snapsim {' '.join(map(str, args))} failed ({done.returncode}):\n"
                                 f"{done.stdout}\n{done.stderr}")
        return done

    def status(self, snap, app):
        path = self.root / "run" / "snapsim" / "services" / f"snap.{snap}.{app}.json"
        return json.loads(path.read_text()) if path.exists() else {"state": "inactive", "main_pid": None}

    def wait_state(self, snap, app, states, timeout=60):
        return wait_until(lambda: self.status(snap, app)["state"] in states and self.status(snap, app), timeout,
                          lambda: f"{snap}.{app} never reached {states}: {self.status(snap, app)}\n"
                                  f"{self.logs(snap)}")

    def logs(self, snap, lines="all"):
        return self.snapsim("logs", "-n", lines, snap, check=False).stdout

    def config(self, snap):
        return json.loads(self.snapsim("get", "-d", snap).stdout)

    def mount(self, snap):
        return self.root / "snap" / snap / "current"

    def shutdown(self):
        """Remove every snap (stopping its services), then kill anything of this root left behind."""
        state_file = self.root / "var" / "lib" / "snapsim" / "state.json"
        if state_file.exists():
            for snap in json.loads(state_file.read_text())["snaps"]:
                self.snapsim("remove", "--purge", snap, check=False)
        for pid in root_processes(self.root):
            ros_harness.kill_quietly(pid, signal.SIGKILL)


def pid_alive(pid):
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def wait_for_file(path, timeout=60):
    return wait_until(lambda: Path(path).exists(), timeout, f"{path} never appeared")


def monotonic():
    return time.monotonic()


# --- a small snap exercising snapsim's snapd behaviour --------------------------------

DEMO_SNAPCRAFT_YAML = """\
name: demo
base: core20
version: '1.0'
summary: snapsim's test snap
description: Apps, services and hooks that record what snapd makes them do.
grade: devel
confinement: strict
environment:
  SNAP_LEVEL: $SNAP/level
parts:
  files:
    plugin: dump
    source: local/
    organize:
      '*.sh': usr/bin/
apps:
  svc:
    command: usr/bin/service.sh
    daemon: simple
    stop-command: usr/bin/on_stop.sh
    post-stop-command: usr/bin/on_post_stop.sh
    stop-timeout: 10s
    command-chain: [usr/bin/chain_one.sh, usr/bin/chain_two.sh]
    extensions: [ros1-noetic]
    environment:
      APP_LEVEL: $SNAP_LEVEL/app
  stubborn:
    command: usr/bin/stubborn.sh
    daemon: simple
    install-mode: disable
    stop-timeout: 1s
  crasher:
    command: usr/bin/exit_with.sh 3
    daemon: simple
    install-mode: disable
  finisher:
    command: usr/bin/exit_with.sh 0
    daemon: simple
    install-mode: disable
  tool:
    command: usr/bin/tool.sh $SNAP_NAME $UNSET_VARIABLE fixed
    command-chain: [usr/bin/chain_one.sh]
    plugs: [network, joystick]
"""

TRACE = 'echo "$1" >>"$SNAP_COMMON/trace"'
DEMO_FILES = {
    "local/trace.sh": f'#!/bin/sh\n{TRACE}\n',
    "local/chain_one.sh": '#!/bin/sh\ntrace.sh chain_one\nexec "$@"\n',
    "local/chain_two.sh": '#!/bin/sh\ntrace.sh chain_two\nexec "$@"\n',
    # Sourced by ros1-launch; clobbers the positional parameters as catkin's setup files may.
    "local/opt/ros/noetic/setup.bash": 'trace.sh ros1-launch\nset -- clobbered\n',
    "local/service.sh": """#!/bin/bash
trace.sh command
env >"$SNAP_COMMON/service-env"
echo "$$" >"$SNAP_COMMON/main.pid"
setsid sleep 1000 &
echo "$!" >"$SNAP_COMMON/grandchild.pid"
trap 'trace.sh command-got-TERM; exit 0' TERM
sleep 1000 &
wait "$!"
""",
    "local/on_stop.sh": """#!/bin/sh
trace.sh stop-command
if kill -0 "$(cat "$SNAP_COMMON/main.pid")" 2>/dev/null; then trace.sh stop-command-saw-main-running; fi
""",
    "local/on_post_stop.sh": """#!/bin/sh
trace.sh post-stop-command
if ! kill -0 "$(cat "$SNAP_COMMON/main.pid")" 2>/dev/null; then trace.sh post-stop-saw-main-gone; fi
""",
    "local/stubborn.sh": """#!/bin/sh
trap '' TERM
echo "$$" >"$SNAP_COMMON/stubborn.pid"
while :; do sleep 1; done
""",
    "local/exit_with.sh": '#!/bin/sh\ntrace.sh "started-$1"\nexit "$1"\n',
    "local/tool.sh": '#!/bin/sh\nprintf "%s\\n" "$@" >"$SNAP_COMMON/tool-args"\nenv >"$SNAP_COMMON/tool-env"\n',
    "snap/hooks/install": """#!/bin/sh
set -e
trace.sh "install-hook svc=$(snapctl services demo.svc | awk 'NR == 2 { print $3 }')"
snapctl set color=red
""",
    "snap/hooks/configure": """#!/bin/sh
set -e
trace.sh "configure-hook svc=$(snapctl services demo.svc | awk 'NR == 2 { print $3 }')"
case "$(snapctl get color)" in
  red | blue) ;;
  *) echo "color: '$(snapctl get color)' is not allowed; allowed values: red, blue" >&2; exit 1 ;;
esac
if [ "$(snapctl get restart-svc)" = "true" ]; then
  snapctl restart demo.svc
  sleep 1
  trace.sh configure-end
fi
""",
    "snap/hooks/post-refresh": '#!/bin/sh\ntrace.sh post-refresh-hook\n',
}


def make_demo_project(folder):
    folder = Path(folder)
    (folder / "snap").mkdir(parents=True)
    (folder / "snap" / "snapcraft.yaml").write_text(DEMO_SNAPCRAFT_YAML)
    for relative, text in DEMO_FILES.items():
        path = folder / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        path.chmod(0o755 if text.startswith("#!") else 0o644)
    return folder


def trace(system, snap="demo"):
    path = system.root / "var" / "snap" / snap / "common" / "trace"
    return path.read_text().splitlines() if path.exists() else []


# --- the real turtlebot3c snap against a test roscore -----------------------------------

MAP_FOLDER = "var/snap/turtlebot3c/common/maps"  # $SNAP_COMMON/maps, for every app and the owner


def emptied_map_folder(system):
    """The snap's map folder, made or emptied: maps, links and a killed save's private folders go."""
    folder = system.root / MAP_FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    for path in folder.iterdir():
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    return folder


def install_turtlebot3c(folder, master):
    """Install this repository's snap in a snapsim root whose services use `master`.

    /etc/environment gives the services the test master's URI, as an owner could
    give theirs; ros_network.sh leaves a URI given on purpose alone.
    """
    system = SnapSystem(Path(folder) / "root", build_dir=ros_harness.BUILD, etc_environment={
        "ROS_MASTER_URI": master.uri, "ROS_HOSTNAME": "127.0.0.1"})
    system.snapsim("install", REPO, "--dangerous")
    system.wait_state("turtlebot3c", "teleop", ["active"])
    master.wait_for_service("/mux/select", timeout=60)
    return system


def app_shell(system, app, script, master_uri, *args, check=True, **env):
    """`snap run --shell turtlebot3c.<app> -c script _ args...` as root on the robot, against `master_uri`."""
    environment = user_environment(ROS_MASTER_URI=master_uri, ROS_HOSTNAME="127.0.0.1", **env)
    return system.snapsim("run", "--shell", f"turtlebot3c.{app}", "-c", script, "_", *args, env=environment,
                          check=check)


def saved_map(maps, name="new_map"):
    """Files as save_map.sh leaves them for install_last_map.sh."""
    (maps / f"{name}.pgm").write_bytes(b"P5\n4 3\n255\n" + bytes(12))
    (maps / f"{name}.yaml").write_text(f"image: /somewhere/{name}.pgm\nresolution: 0.05\n"
                                       "origin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
                                       "free_thresh: 0.196\n")


def dated_maps(maps):
    """The names of the maps' YAML files (the current map's link aside), sorted."""
    return sorted(path.name for path in maps.glob("*.yaml") if path.name != "current_map.yaml")


def main_command_line(system, app):
    """The command line of a service's main process once its chain has exec'd roslaunch."""
    def launched():
        pid = system.wait_state("turtlebot3c", app, ["active"])["main_pid"]
        try:
            words = Path(f"/proc/{pid}/cmdline").read_bytes().decode().rstrip("\0").split("\0")
        except OSError:
            return None
        return words if any(word.endswith(("/roslaunch", "/roslaunch_joining.py")) for word in words) else None
    return wait_until(launched, 60, lambda: f"{app} never exec'd roslaunch:\n{system.logs('turtlebot3c')}")


def mux_mark(master):
    """How many /mux/selected messages the probe has seen: selections after this are new."""
    master.probe.subscribe("/mux/selected", "std_msgs/String")
    return master.probe.count("/mux/selected")


def selected_mux_input(master, expected, since, timeout=30):
    """Wait until /mux/selected says `expected` in a message received after mark `since`."""
    message = master.probe.wait_for_message("/mux/selected", "std_msgs/String", timeout=timeout,
                                            where=lambda message: message["data"] == expected, start=since)
    return message["data"]


# --- the snap serving its own master (the roscore app) --------------------------------

# What each daemon runs while it works (core's drivers only with simulation=false).
DAEMON_NODES = {
    "core": ["/robot_state_publisher"],
    "teleop": ["/mux", "/velocity_watchdog"],
    "mapping": ["/turtlebot3_slam_gmapping", "/mapping_recorder"],
    "navigation": ["/map_server", "/amcl", "/move_base"],
}
DRIVER_NODES = ["/turtlebot3_core", "/turtlebot3_lds"]


def install_with_own_master(folder):
    """This repository's snap installed in a snapsim root whose roscore app runs the master.

    /etc/environment names a free port (never 11311, so a developer's roscore and parallel
    tests are never met); returns (system, master): `master` starts nothing, it is the
    test's handle on that port (launch, probe, graph queries).
    """
    folder = Path(folder)
    master = ros_harness.RosMaster(ros_harness.install_space_environment(), folder / "ros", start_core=False)
    system = SnapSystem(folder / "root", build_dir=ros_harness.BUILD, etc_environment={
        "ROS_MASTER_URI": master.uri, "ROS_HOSTNAME": "127.0.0.1"})
    system.snapsim("install", REPO, "--dangerous")
    return system, master


def command_words(pid):
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace").rstrip("\0").split("\0")
    except OSError:
        return []


def rosmaster_pids(system):
    """The rosmaster processes running in `system`'s root."""
    return [pid for pid in root_processes(system.root)
            if any(Path(word).name == "rosmaster" for word in command_words(pid)) and pid_alive(pid)]


def kill_master(system, master):
    """SIGKILL the master the roscore app runs (a crash); the probe goes with it."""
    close_probe(master)
    pids = rosmaster_pids(system)
    for pid in pids:
        ros_harness.kill_quietly(pid, signal.SIGKILL)
    return pids


def close_probe(master):
    """Drop the test's probe node: one registered with a master that has died is seen by nobody."""
    if master._probe is not None:
        master._probe.close()
        master._probe = None


class _Timeout(xmlrpc.client.Transport):
    def make_connection(self, host):
        connection = super().make_connection(host)
        connection.timeout = 3.0
        return connection


def node_uri(master, name):
    """The XML-RPC URI `name` is registered under, if its process answers there (else None)."""
    try:
        code, _, uri = xmlrpc.client.ServerProxy(master.uri, transport=_Timeout()).lookupNode("/test", name)
        if code != 1:
            return None
        code, _, pid = xmlrpc.client.ServerProxy(uri, transport=_Timeout()).getPid("/test")
    except (OSError, xmlrpc.client.Error):
        return None
    return (uri, pid) if code == 1 else None


def active_apps(system):
    return [app for app in DAEMON_NODES if system.status("turtlebot3c", app)["state"] == "active"]


def robot_problems(system, master, apps=None, simulation=None):
    """What keeps the robot from working now (empty: it works): the master answers; every node
    of each active daemon (or of `apps`) is registered and answers; robot_state_publisher
    publishes the model's /tf_static; the watchdog carries the mux's output to /cmd_vel; and
    /mux/select answers (asked for the input already selected, so nothing changes)."""
    if not ros_harness.master_answers(master.uri):
        return ["no master answers"]
    apps = active_apps(system) if apps is None else apps
    names = [name for app in apps for name in DAEMON_NODES[app]]
    if "core" in apps and simulation is False:
        names += DRIVER_NODES
    problems = [f"{name} is not registered or does not answer" for name in names if node_uri(master, name) is None]
    try:
        publishers, subscribers, _ = master.system_state()
    except (OSError, AssertionError) as error:
        return problems + [f"getSystemState: {error}"]
    publishers, subscribers = dict(publishers), dict(subscribers)
    wanted = []
    if "core" in apps:
        wanted += [("/tf_static", publishers, "/robot_state_publisher")]
    if "teleop" in apps:
        # (the mux advertises its output only once an input has spoken: not asked here)
        wanted += [("/cmd_vel_mux", subscribers, "/velocity_watchdog"), ("/cmd_vel", publishers, "/velocity_watchdog")]
    problems += [f"{node} is not on {topic}" for topic, table, node in wanted if node not in table.get(topic, [])]
    if "teleop" in apps and not problems:
        problems += mux_select_problems(master)
    return problems


def mux_select_problems(master):
    try:
        selected = master.probe.wait_for_message("/mux/selected", "std_msgs/String", timeout=5, start=0)["data"]
        master.probe.call("/mux/select", {"topic": selected}, timeout=5.0)
    except (ros_harness.ProbeError, TimeoutError, OSError) as error:
        close_probe(master)  # a probe of a master that died: the next look makes a new one
        return [f"/mux/select does not answer: {error}"]
    return []


def wait_for_working_robot(system, master, timeout, **kwargs):
    """Wait until `robot_problems` finds nothing; returns the seconds it took."""
    started = time.monotonic()
    wait_until(lambda: not robot_problems(system, master, **kwargs), timeout,
               lambda: f"the robot did not work within {timeout} s: {robot_problems(system, master, **kwargs)}\n"
                       f"{system.snapsim('services', check=False).stdout}\n{system.logs('turtlebot3c', '150')}",
               interval=0.25)
    return time.monotonic() - started
