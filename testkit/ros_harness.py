"""Run real ROS 1 from tests: a roscore per test module, processes, launches, waits.

Everything runs from the install spaces built by `tools/build` (the snap's
`build/prime/opt/ros/noetic`, then `build/sim`), never from `src/`, so a
missing install rule fails a test. Every process started here carries a marker
in its environment; `kill_marked_processes` finds and kills whatever is left,
including nodes that roslaunch put in sessions of their own.
"""
import json
import os
import platform
import random
import signal
import socket
import subprocess
import sys
import tempfile
import time
import xmlrpc.client
from pathlib import Path

from testkit.waiting import wait_until

REPO = Path(__file__).resolve().parent.parent
BUILD = Path(os.environ.get("TURTLEBOT3C_BUILD_DIR", REPO / "build"))
PRIME_ROS = BUILD / "prime" / "opt" / "ros" / "noetic"
SIM_SPACE = BUILD / "sim"
VENV = Path(os.environ.get("TURTLEBOT3C_VENV", REPO / ".venv"))
RUN_MARKER = "TURTLEBOT3C_TEST_RUN"
RUN_ID = f"{os.getpid()}-{int(time.time() * 1000)}"


# Test masters' ports lie from here to below the kernel's ephemeral range: above roscore's
# default 11311, a master someone else may start.
FIRST_TEST_PORT = 20000
_ports_handed_out = set()
_port_choice = random.SystemRandom()


def first_ephemeral_port():
    """The first of the ports the kernel hands out by itself (to a bind to port 0, to an outgoing connection)."""
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768  # Linux's default


def free_port():
    """A TCP port nobody listens on now, below the kernel's ephemeral range and never 11311.

    A port from the ephemeral range can be handed to another process (a node's XML-RPC
    server, an outgoing connection) before the master that was meant for it binds it; that
    master then never comes up ("Address already in use", once in CI). Below the range, only
    another test's pick can take it, and each pick here is random and handed out once.
    """
    first_ephemeral = first_ephemeral_port()
    while True:
        port = _port_choice.randrange(FIRST_TEST_PORT, max(first_ephemeral, FIRST_TEST_PORT + 1000))
        if port in _ports_handed_out:
            continue
        with socket.socket() as sock:
            try:
                sock.bind(("127.0.0.1", port))
            except OSError:
                continue
        _ports_handed_out.add(port)
        return port


def sourced_environment(setup_files, base=None):
    """The environment after sourcing each catkin setup.bash in turn."""
    script = "".join(f'source "{path}" --extend; ' for path in setup_files) + "env -0"
    output = subprocess.run(["bash", "-c", script], env=base, check=True, capture_output=True).stdout
    return dict(item.split("=", 1) for item in output.decode().split("\0") if "=" in item)


def install_space_environment():
    """Environment for running the installed workspace (and simulator, if built)."""
    if not (PRIME_ROS / "setup.bash").exists():
        raise RuntimeError(f"no install space at {PRIME_ROS}: run tools/build first")
    setup_files = [PRIME_ROS / "setup.bash"]
    if (SIM_SPACE / "setup.bash").exists():
        setup_files.append(SIM_SPACE / "setup.bash")
    base = {key: value for key, value in os.environ.items() if not key.startswith("ROS_")}
    # Our virtualenv's python3 first: installed nodes run `/usr/bin/env python3`.
    base["PATH"] = "{}:{}".format(VENV / "bin", base.get("PATH", "/usr/bin:/bin"))
    for key in ("PYTHONPATH", "CMAKE_PREFIX_PATH", "ROS_PACKAGE_PATH"):
        base.pop(key, None)
    env = sourced_environment(setup_files, base)
    env[RUN_MARKER] = RUN_ID
    env["PYTHONUNBUFFERED"] = "1"
    return env


class Process:
    """A child process in its own session, logging to a file."""

    def __init__(self, args, env, log_path, name=None, cwd=None, stdin=subprocess.DEVNULL):
        self.args = [str(arg) for arg in args]
        self.name = name or Path(self.args[0]).name
        self.log_path = Path(log_path)
        self._log = open(self.log_path, "ab")
        self.popen = subprocess.Popen(
            self.args, env=env, cwd=cwd, stdin=stdin, stdout=self._log, stderr=subprocess.STDOUT,
            start_new_session=True)
        self.pid = self.popen.pid

    def running(self):
        return self.popen.poll() is None

    def wait(self, timeout):
        return self.popen.wait(timeout)

    def log_text(self):
        return self.log_path.read_text(errors="replace")

    def tail(self, lines=30):
        """The last lines of its log, for a message saying why it stopped."""
        try:
            return "\n".join(self.log_text().splitlines()[-lines:])
        except OSError:
            return ""

    def signal(self, signum):
        try:
            os.killpg(self.pid, signum)
        except ProcessLookupError:
            pass

    def stop(self, grace=5.0):
        """SIGINT (roslaunch's clean shutdown), then SIGTERM, then SIGKILL, descendants included."""
        family = descendants(self.pid)
        for signum, wait in ((signal.SIGINT, grace), (signal.SIGTERM, 2.0)):
            if not self.running():
                break
            self.signal(signum)
            try:
                self.popen.wait(wait)
            except subprocess.TimeoutExpired:
                pass
        for pid in [self.pid] + family + descendants(self.pid):
            kill_quietly(pid, signal.SIGKILL)
        try:
            self.popen.wait(2.0)
        except subprocess.TimeoutExpired:
            pass
        self._log.close()


def _proc_children():
    children = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        parent = int(stat.rsplit(")", 1)[1].split()[1])
        children.setdefault(parent, []).append(int(entry.name))
    return children


def descendants(pid):
    children = _proc_children()
    found, frontier = [], [pid]
    while frontier:
        for child in children.get(frontier.pop(), []):
            found.append(child)
            frontier.append(child)
    return found


def kill_quietly(pid, signum):
    try:
        os.kill(pid, signum)
    except (ProcessLookupError, PermissionError):
        pass


def marked_processes(run_id=RUN_ID):
    """Pids of live processes started by this test run (found by their environment marker)."""
    marker = f"{RUN_MARKER}={run_id}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            environ = (entry / "environ").read_bytes()
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if state != "Z" and marker in environ.split(b"\0"):
            found.append(int(entry.name))
    return found


def kill_marked_processes(run_id=RUN_ID):
    pids = marked_processes(run_id)
    for pid in pids:
        kill_quietly(pid, signal.SIGKILL)
    return pids


def master_answers(uri):
    """Whether a ROS master answers at `uri` now."""
    try:
        return xmlrpc.client.ServerProxy(uri).getPid("/turtlebot3c_test")[0] == 1
    except OSError:
        return False


class RosMaster:
    """A roscore on a free port, with helpers to start nodes and launch files against it.

    `start_core=False`: the port only, for a master someone else runs there (the snap's roscore app)."""

    def __init__(self, base_env, workdir, start_core=True):
        self.port = free_port()
        self.uri = f"http://127.0.0.1:{self.port}"
        self.workdir = Path(workdir)
        self.workdir.mkdir(parents=True, exist_ok=True)
        self.env = dict(base_env)
        self.env.update({
            "ROS_MASTER_URI": self.uri,
            "ROS_HOSTNAME": "127.0.0.1",
            "ROS_HOME": str(self.workdir / "ros_home"),
            "ROS_LOG_DIR": str(self.workdir / "ros_log"),
        })
        self.env.pop("ROS_IP", None)
        self.processes = []
        self._probe = None
        self.core = None
        if not start_core:
            return
        self.core = self.start(["roscore", "-p", str(self.port)], name="roscore")
        wait_until(self.is_up, 30,
                   lambda: f"roscore on port {self.port} did not come up:\n{self.core.log_text()[-2000:]}")

    def is_up(self):
        return master_answers(self.uri)

    def master_api(self):
        return xmlrpc.client.ServerProxy(self.uri)

    def start(self, args, name=None, env=None, **kwargs):
        name = name or Path(str(args[0])).name
        log_path = self.workdir / "{:02d}-{}.log".format(len(self.processes), name.replace("/", "_"))
        process = Process(args, env or self.env, log_path, name=name, **kwargs)
        self.processes.append(process)
        return process

    def launch(self, package, launch_file, *launch_args, **kwargs):
        """Start `roslaunch package launch_file arg:=value ...` against this master."""
        args = ["roslaunch", "--wait", package, launch_file] + list(launch_args)
        return self.start(args, name=f"roslaunch-{Path(launch_file).stem}", **kwargs)

    def rosrun(self, package, executable, *args, **kwargs):
        return self.start(["rosrun", package, executable] + list(args), name=executable, **kwargs)

    def rosrun_refused(self, package, executable, parameter, timeout=30):
        """Run `executable` with one private `parameter` (`_name:=value`) it should refuse, under a
        node name of its own (a private parameter outlives its node on the master, and would reach
        the next node of that name); wait for it to stop. (exit status, its log)."""
        name = f"{executable}_refusing_{parameter.split(':=')[0].lstrip('_')}"
        node = self.rosrun(package, executable, f"__name:={name}", parameter)
        wait_until(lambda: not node.running(), timeout, f"{executable} kept running with {parameter}")
        return node.popen.returncode, node.log_text()

    @property
    def probe(self):
        if self._probe is None:
            self._probe = RosProbe(self)
        return self._probe

    # --- the computation graph, read straight from the master -------------------------

    def system_state(self):
        code, _, state = self.master_api().getSystemState("/test")
        assert code == 1, state
        return state

    def node_names(self):
        names = set()
        for group in self.system_state():
            for _, nodes in group:
                names.update(nodes)
        return names

    def publishers(self, topic):
        return next((nodes for name, nodes in self.system_state()[0] if name == topic), [])

    def services(self):
        return {name for name, _ in self.system_state()[2]}

    def param(self, name):
        code, message, value = self.master_api().getParam("/test", name)
        if code != 1:
            raise KeyError(f"{name}: {message}")
        return value

    def wait_for_node(self, name, timeout=20):
        return wait_until(lambda: name in self.node_names(), timeout,
                          lambda: f"node {name} never registered; nodes: {sorted(self.node_names())}")

    def wait_for_publisher(self, topic, timeout=20):
        return wait_until(lambda: self.publishers(topic), timeout, f"nobody published {topic}")

    def wait_for_service(self, service, timeout=20):
        return wait_until(lambda: service in self.services(), timeout,
                          f"service {service} never appeared")

    def logs(self, tail=3000):
        """The end of every log this master's processes wrote, for failure reports."""
        parts = []
        for process in self.processes:
            text = process.log_text() if process.log_path.exists() else ""
            parts.append(f"----- {process.name} ({process.log_path}) -----\n{text[-tail:]}")
        return "\n".join(parts)

    def shutdown(self):
        if self._probe is not None:
            self._probe.close()
        for process in reversed(self.processes):
            process.stop()


class ProbeError(RuntimeError):
    pass


class RosProbe:
    """Client side of testkit/rosprobe.py: a rospy node in a child process."""

    def __init__(self, master):
        # A master-like object may name a command prefix, e.g. `ip netns exec NS` for another test host.
        prefix = list(getattr(master, "command_prefix", []))
        self.process = subprocess.Popen(
            prefix + [str(VENV / "bin" / "python3"), str(Path(__file__).with_name("rosprobe.py"))],
            env=master.env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
            stderr=open(master.workdir / "probe.log", "ab"), start_new_session=True, text=True)
        ready = json.loads(self.process.stdout.readline() or '{"ok": false}')
        if not ready.get("ok"):
            raise ProbeError("test probe failed to start; see {}".format(master.workdir / "probe.log"))

    def request(self, op, **arguments):
        self.process.stdin.write(json.dumps(dict(arguments, op=op)) + "\n")
        self.process.stdin.flush()
        line = self.process.stdout.readline()
        if not line:
            raise ProbeError(f"test probe died during {op}")
        answer = json.loads(line)
        if not answer.pop("ok"):
            raise ProbeError("{} failed: {}".format(op, answer["error"]))
        return answer

    def subscribe(self, topic, type):
        self.request("subscribe", topic=topic, type=type)

    def messages(self, topic, start=0):
        return [entry["msg"] for entry in self.request("messages", topic=topic, start=start)["messages"]]

    def timed_messages(self, topic, start=0):
        return self.request("messages", topic=topic, start=start)["messages"]

    def count(self, topic):
        return self.request("messages", topic=topic, start=1 << 62)["count"]

    def wait_for_message(self, topic, type, timeout=20, where=lambda message: True, start=None):
        """The first message on `topic` (after index `start`, default: now) satisfying `where`."""
        self.subscribe(topic, type)
        start = self.count(topic) if start is None else start

        def matching():
            return next((message for message in self.messages(topic, start) if where(message)), None)
        return wait_until(matching, timeout, f"no matching message on {topic}")

    def publish(self, topic, type, msg=None, latch=False):
        return self.request("publish", topic=topic, type=type, msg=msg or {}, latch=latch)

    def call(self, service, request=None, timeout=5.0):
        return self.request("call", service=service, request=request or {}, timeout=timeout)["response"]

    def transform(self, target, source, timeout=5.0):
        return self.request("transform", target=target, source=source, timeout=timeout)["transform"]

    def close(self):
        try:
            self.process.stdin.close()
            self.process.wait(3)
        except (OSError, subprocess.TimeoutExpired):
            pass
        kill_quietly(self.process.pid, signal.SIGKILL)


def new_workdir(prefix):
    return Path(tempfile.mkdtemp(prefix=f"turtlebot3c-{prefix}-"))


def python():
    return str(VENV / "bin" / "python3") if (VENV / "bin" / "python3").exists() else sys.executable


BENCH_INSIDE = "TURTLEBOT3C_BENCH_INSIDE"


# What a benchmark measuring CPU time and figures needs: one core (BLAS would use both and count
# their time), and numpy's sin/cos without AVX-512. numpy 1.22+ computes them there in SIMD code
# whose last bits differ from the scalar code's, so that a SLAM's discrete choices (a loop closure
# taken or not) give another map from the same inputs on a machine with AVX-512 than on one
# without (freiburg-079, severe: 194 against 202 closures). Off, the figures are the same on
# both. The snap's numpy 1.17 has no such code, and ignores the variable.
# On one machine too, that code gives a strided column last bits that depend on its address,
# which made runs differ; our code takes them on contiguous copies (se2.cos_sin).
SINGLE_CORE_REPRODUCIBLE = {
    "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
    "NPY_DISABLE_CPU_FEATURES": "AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL",
}


def cpuinfo(field):
    """The values of /proc/cpuinfo's `field` ("model name", "flags", ...), one per logical CPU;
    none where there is no such file."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as lines:
            return [line.split(":", 1)[1].strip() for line in lines if line.split(":", 1)[0].strip() == field]
    except OSError:
        return []


# OpenBLAS picks its kernels by CPU as well, and they differ in the last bits. On an AMD EPYC
# with AVX-512 (Zen 4), Debian's OpenBLAS picks Cooperlake's, and freiburg-079 mild closed 208
# loops (5 the reference disagrees with), against 206 (2) with Haswell's or Zen's; core20's numpy
# bundles an OpenBLAS too old to know that CPU, which falls back to Barcelona's. Where the CPU
# has AVX2, the benchmarks take Haswell's kernels, on both runtimes.
if platform.machine() == "x86_64" and {"avx2", "fma"} <= set((cpuinfo("flags") or [""])[0].split()):
    SINGLE_CORE_REPRODUCIBLE["OPENBLAS_CORETYPE"] = "Haswell"


def run_in_install_space(script, **extra_env):
    """For the benchmarks in benchmarks/: unless it already runs there, run `script` again, with the same
    arguments, in the install spaces' environment (rospy, our packages) plus `extra_env`, on
    $TURTLEBOT3C_VENV's Python (.venv's unless set: .venv-core20 runs it on the snap's runtime)."""
    if os.environ.get(BENCH_INSIDE) == "1":
        return
    env = install_space_environment()
    env.update(extra_env)
    # testkit itself: .venv has it installed (editable), another virtualenv may not.
    env["PYTHONPATH"] = os.pathsep.join(filter(None, (str(REPO), env.get("PYTHONPATH"))))
    env[BENCH_INSIDE] = "1"
    os.execve(python(), [python(), str(script)] + sys.argv[1:], env)
