"""systemd's part for one snap service: run it, stop it, restart it, log it.

`snapsim start` spawns one supervisor per service, in the background. It starts
the app's command as `snap run` would, copies its output to the journal, and
writes the service's status to a JSON file. SIGTERM to the supervisor is a stop
request. Like systemd with snapd's unit files:

- stop: stop-command (bounded by stop-timeout), then SIGTERM to every process of
  the service's "cgroup" (or only the main one for a stop-mode without -all),
  SIGKILL to what is left after stop-timeout, then post-stop-command;
- the same stop-command / kill / post-stop-command sequence runs when the main
  process exits by itself, before restart-condition decides on a restart;
- restarts wait restart-delay (default 100 ms) and are rate limited as
  systemd's defaults do: a 6th start within 10 s fails the service.

The "cgroup" is every process carrying the service's marker in its environment
(inherited through fork and exec, even by processes that start their own
session, as roslaunch's nodes do). The supervisor is a child subreaper, so
orphaned processes of the service are reparented to it and reaped.
"""
import collections
import ctypes
import json
import os
import select
import signal
import subprocess
import time
import traceback
from pathlib import Path

from . import environment, journal
from .state import read as read_state

PR_SET_CHILD_SUBREAPER = 36
START_LIMIT_INTERVAL = 10.0
START_LIMIT_BURST = 5
DEFAULT_RESTART_DELAY = 0.1
DEFAULT_STOP_TIMEOUT = 30.0
CLEAN_SIGNALS = {signal.SIGHUP, signal.SIGINT, signal.SIGTERM, signal.SIGPIPE}
STOP_SIGNALS = {"sigterm": signal.SIGTERM, "sighup": signal.SIGHUP, "sigusr1": signal.SIGUSR1,
                "sigusr2": signal.SIGUSR2, "sigint": signal.SIGINT}


def parse_duration(text, default):
    """snapcraft's durations: "300s", "2m", "500ms", "10" (seconds)..."""
    if text is None:
        return default
    text = str(text)
    for suffix, scale in (("ns", 1e-9), ("us", 1e-6), ("ms", 1e-3), ("s", 1.0), ("m", 60.0)):
        if text.endswith(suffix) and text[:-len(suffix)].isdigit():
            return int(text[:-len(suffix)]) * scale
    return float(text)


def cgroup_marker(layout, snap, app):
    return f"{journal.unit_name(snap, app)}@{layout.root}"


def cgroup_members(marker):
    entry = f"SNAPSIM_CGROUP={marker}".encode()
    return [pid for pid, environ, _ in _live_processes() if entry in environ]


def root_processes(root):
    """Every process of the snapsim root `root`: its services' "cgroups" and their supervisors.

    For whoever must leave nothing of a root running (the demo's clean-up, tests),
    also after a supervisor was killed and its service's processes were orphaned.
    """
    root = str(Path(root).resolve()).encode()
    marker_end = b"@" + root
    found = []
    for pid, environ, argv in _live_processes():
        in_cgroup = any(item.startswith(b"SNAPSIM_CGROUP=") and item.endswith(marker_end) for item in environ)
        supervisor = b"_supervise" in argv and root in argv
        if in_cgroup or supervisor:
            found.append(pid)
    return found


def _live_processes():
    """(pid, environment entries, argv) of every process but this one and zombies, as bytes."""
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit() or int(proc.name) == os.getpid():
            continue
        try:
            environ = (proc / "environ").read_bytes().split(b"\0")
            argv = (proc / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if not is_zombie(int(proc.name)):
            yield int(proc.name), environ, argv


def is_zombie(pid):
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except (OSError, IndexError):
        return True


def should_restart(condition, exit_code, exit_signal):
    """systemd's Restart= decision for a main process that exited by itself."""
    clean = exit_code == 0 if exit_signal is None else exit_signal in CLEAN_SIGNALS
    unclean_signal = exit_signal is not None and not clean
    return {
        "never": False, "no": False, "always": True, "on-success": clean, "on-failure": not clean,
        "on-abnormal": unclean_signal, "on-abort": unclean_signal, "on-watchdog": False,
    }[condition]


class Supervisor:
    def __init__(self, layout, snap, app):
        self.layout = layout
        self.snap = snap
        self.app_name = app
        snap_state = read_state(layout)["snaps"][snap]
        self.revision = snap_state["revision"]
        self.cookie = snap_state["cookie"]
        self.info = _snap_yaml(layout, snap, self.revision)
        self.app = self.info["apps"][app]
        self.unit = journal.unit_name(snap, app)
        self.marker = cgroup_marker(layout, snap, app)
        self.stop_timeout = parse_duration(self.app.get("stop-timeout"), DEFAULT_STOP_TIMEOUT)
        self.restart_delay = parse_duration(self.app.get("restart-delay"), DEFAULT_RESTART_DELAY)
        self.restart_condition = self.app.get("restart-condition", "on-failure")
        stop_mode = self.app.get("stop-mode", "sigterm-all")
        self.kill_all = stop_mode.endswith("-all")
        self.kill_signal = STOP_SIGNALS[stop_mode.replace("-all", "")]
        self.status = {"supervisor": os.getpid(), "state": "activating", "main_pid": None, "starts": 0,
                       "restarts": 0, "result": None, "exit_code": None, "exit_signal": None}
        self.exited = {}  # pid -> wait status, for children reaped by the SIGCHLD loop
        self.children = {}  # pid -> Popen, of children not reaped yet
        self.stop_requested = False

    # --- plumbing ---------------------------------------------------------------------
    def log(self, message):
        journal.write(self.layout, self.unit, "systemd", 1, f"{self.unit}: {message}")

    def save_status(self, **changes):
        self.status.update(changes)
        path = self.layout.service_status(self.snap, self.app_name)
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_suffix(f".{os.getpid()}.tmp")
        temporary.write_text(json.dumps(self.status))
        os.replace(temporary, path)

    def install_signal_handlers(self):
        read_end, write_end = os.pipe()
        os.set_blocking(write_end, False)
        self.wakeup = read_end
        signal.set_wakeup_fd(write_end)
        signal.signal(signal.SIGCHLD, lambda *_: None)
        signal.signal(signal.SIGTERM, self._on_stop_request)
        signal.signal(signal.SIGINT, self._on_stop_request)

    def _on_stop_request(self, *_):
        self.stop_requested = True

    def sleep(self, seconds):
        """Wait up to `seconds`, waking early for a signal; reap children meanwhile."""
        ready, _, _ = select.select([self.wakeup], [], [], max(seconds, 0))
        if ready:
            os.read(self.wakeup, 4096)
        self.reap()

    def reap(self):
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            self.exited[pid] = status
            self.children.pop(pid, None)

    def spawn(self, command, ident):
        argv, env, cwd = environment.app_command(
            self.layout, self.info, self.revision, self.app_name, command, service=True, cookie=self.cookie)
        env["SNAPSIM_CGROUP"] = self.marker
        try:
            process = subprocess.Popen(argv, env=env, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                       stderr=subprocess.STDOUT, start_new_session=True)
        except OSError as error:
            self.log(f"Failed to execute {argv[0]}: {error}")
            return None
        journal.follow_stream(self.layout, self.unit, ident, process.pid, process.stdout)
        # Keep the Popen object until the child is reaped here: a collected Popen
        # polls its child and would take the exit status from us.
        self.children[process.pid] = process
        return process.pid

    def wait_exit(self, pid, timeout, until_stop_request=False):
        """The wait status of child `pid`, or None if it is still running after `timeout` s
        (or, with `until_stop_request`, when a stop is requested)."""
        deadline = time.monotonic() + timeout
        while pid not in self.exited:
            remaining = deadline - time.monotonic()
            if remaining <= 0 or (until_stop_request and self.stop_requested):
                return None
            self.sleep(min(remaining, 1.0))
        return self.exited.pop(pid)

    # --- the service's life -----------------------------------------------------------
    def run(self):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0)
        self.install_signal_handlers()
        starts = collections.deque()
        ident = f"{self.snap}.{self.app_name}"
        while True:
            now = time.monotonic()
            while starts and now - starts[0] > START_LIMIT_INTERVAL:
                starts.popleft()
            if len(starts) >= START_LIMIT_BURST:
                self.log("Start request repeated too quickly.")
                self.log("Failed with result 'start-limit-hit'.")
                self.save_status(state="failed", result="start-limit-hit", main_pid=None)
                break
            starts.append(now)
            main = self.spawn("", ident)
            if main is None:
                self.save_status(state="failed", result="exec", main_pid=None)
                break
            self.status["starts"] += 1
            self.save_status(state="active", main_pid=main)
            self.log(f"Started Service for snap application {ident}.")

            status = None
            while status is None and not self.stop_requested:
                status = self.wait_exit(main, 3600, until_stop_request=True)
            if status is None:  # stop requested while running
                self.log(f"Stopping Service for snap application {ident}...")
                self.save_status(state="deactivating")
                result = self.stop_sequence(main)
                self.save_status(state="inactive" if result == "success" else "failed", result=result,
                                 main_pid=None)
                self.log(f"Stopped Service for snap application {ident}.")
                break

            code, sig = _decode(status)
            self.save_status(state="deactivating", main_pid=None, exit_code=code, exit_signal=sig)
            how = f"code=exited, status={code}" if sig is None else f"code=killed, signal={signal.Signals(sig).name}"
            self.log(f"Main process exited, {how}")
            self.stop_sequence(None)
            if self.stop_requested:
                self.save_status(state="inactive", result="success")
                break
            if should_restart(self.restart_condition, code, sig):
                self.save_status(state="activating", result="exit-code" if sig is None else "signal")
                restart_at = time.monotonic() + self.restart_delay
                while time.monotonic() < restart_at and not self.stop_requested:
                    self.sleep(restart_at - time.monotonic())
                if self.stop_requested:
                    self.save_status(state="inactive", result="success")
                    break
                self.status["restarts"] += 1
                self.log(f"Scheduled restart job, restart counter is at {self.status['restarts']}.")
                continue
            clean = not should_restart("on-failure", code, sig)
            self.save_status(state="inactive" if clean else "failed",
                             result="success" if clean else ("exit-code" if sig is None else "signal"))
            if not clean:
                self.log(f"Failed with result '{self.status['result']}'.")
            break
        self.status["supervisor"] = None
        self.save_status()

    def stop_sequence(self, main):
        """stop-command, SIGTERM the cgroup, SIGKILL after stop-timeout, post-stop-command."""
        result = "success"
        if "stop-command" in self.app:
            self.run_control("stop")
        targets = self.members() if self.kill_all else ([main] if main else [])
        for pid in targets:
            _signal(pid, self.kill_signal)
        if not self.wait_gone(targets, self.stop_timeout):
            self.log("State 'stop-sigterm' timed out. Killing.")
            for pid in self.members() if self.kill_all else targets:
                _signal(pid, signal.SIGKILL)
            self.wait_gone(self.members(), 5.0)
            result = "timeout"
        if main and main in self.exited:
            self.exited.pop(main)
        if "post-stop-command" in self.app:
            self.run_control("post-stop")
        if self.kill_all:  # systemd's final SIGKILL for whatever the post-stop left behind
            for pid in self.members():
                _signal(pid, signal.SIGKILL)
        return result

    def run_control(self, command):
        """Run the stop or post-stop command through the command-chain, bounded by stop-timeout."""
        pid = self.spawn(command, f"{self.snap}.{self.app_name}")
        if pid is None:
            return
        status = self.wait_exit(pid, self.stop_timeout)
        if status is None:
            self.log(f"{command}-command timed out after {self.stop_timeout:g} s. Killing.")
            _signal(pid, signal.SIGKILL, group=True)
            self.wait_exit(pid, 5.0)
            return
        code, sig = _decode(status)
        if code != 0:
            what = f"status={code}" if sig is None else f"signal={signal.Signals(sig).name}"
            self.log(f"Control process ({command}-command) exited, {what}")

    def members(self):
        return cgroup_members(self.marker)

    def wait_gone(self, pids, timeout):
        deadline = time.monotonic() + timeout
        rescan = time.monotonic() + 1.0
        alive = [pid for pid in pids if not is_zombie(pid)]
        while alive:
            if time.monotonic() >= deadline:
                return False
            self.sleep(0.05)
            alive = [pid for pid in alive if not is_zombie(pid)]
            if self.kill_all and time.monotonic() >= rescan:
                alive = sorted(set(alive) | set(self.members()))
                rescan = time.monotonic() + 1.0
        return True


def _decode(status):
    if os.WIFSIGNALED(status):
        return None, os.WTERMSIG(status)
    return os.WEXITSTATUS(status), None


def _signal(pid, signum, group=False):
    try:
        if group:
            os.killpg(pid, signum)
        else:
            os.kill(pid, signum)
    except (ProcessLookupError, PermissionError):
        pass


def _snap_yaml(layout, snap, revision):
    import yaml
    return yaml.safe_load((layout.snap_mount(snap, revision) / "meta" / "snap.yaml").read_text())


def supervise(layout, snap, app):
    try:
        Supervisor(layout, snap, app).run()
    except Exception:
        # The supervisor has no terminal: its own failure goes to the journal.
        journal.write(layout, journal.unit_name(snap, app), "snapsim", os.getpid(), traceback.format_exc())
        raise
