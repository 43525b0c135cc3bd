"""`snap start/stop/restart/services`: what snapd asks of systemd, done with supervisors."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from . import state as state_module
from .state import SnapError
from .supervisor import DEFAULT_STOP_TIMEOUT, is_zombie, parse_duration

# snapsim itself and its snapctl, as its own processes (supervisors, hooks and apps) run them: with the
# interpreter running this.
COMMAND = (sys.executable, "-m", "snapsim")
SNAPCTL_COMMAND = (sys.executable, "-m", "snapsim.snapctl")


def status(layout, snap, app):
    """The service's status file, with "state" corrected to inactive if its supervisor died."""
    path = layout.service_status(snap, app)
    try:
        current = json.loads(path.read_text())
    except (FileNotFoundError, ValueError):
        return {"state": "inactive", "supervisor": None, "main_pid": None, "starts": 0, "restarts": 0}
    if current.get("supervisor") and not supervisor_alive(current["supervisor"]):
        current.update(state="failed" if current.get("state") == "failed" else "inactive", supervisor=None)
    return current


def supervisor_alive(pid):
    try:
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    return b"_supervise" in cmdline and not is_zombie(pid)


def is_active(layout, snap, app):
    return status(layout, snap, app)["state"] in ("active", "activating", "deactivating")


def daemons(snap_info):
    """The snap's services in snapd's start order: each after those it names in `after` and those
    naming it in `before` (systemd's After=/Before= between the snap's units), else by name.
    Stopping goes in the reverse order. Ordering only: starting one service starts no other."""
    apps = snap_info.get("apps", {})
    names = sorted(name for name, app in apps.items() if "daemon" in app)
    earlier = {name: set() for name in names}
    for name in names:
        for key in ("after", "before"):
            for other in apps[name].get(key) or []:
                if other not in earlier:
                    raise SnapError(f'cannot validate snap "{snap_info.get("name")}": '
                                    f'invalid definition of application "{name}": '
                                    f'{key} references app "{other}", which is not a service')
                if key == "after":
                    earlier[name].add(other)
                else:
                    earlier[other].add(name)
    ordered = []
    while len(ordered) < len(names):
        ready = [name for name in names if name not in ordered and earlier[name] <= set(ordered)]
        if not ready:
            cycle = ", ".join(name for name in names if name not in ordered)
            raise SnapError(f'cannot validate snap "{snap_info.get("name")}": '
                            f"applications are part of a before/after cycle: {cycle}")
        ordered.append(ready[0])
    return ordered


def in_start_order(layout, targets):
    """[(snap, app)] sorted as systemd orders one transaction's start jobs (stop jobs: reversed)."""
    order = {}
    for snap in dict.fromkeys(snap for snap, _ in targets):
        order.update(((snap, app), index) for index, app in enumerate(daemons(snap_info(layout, snap))))
    return sorted(dict.fromkeys(targets), key=lambda target: (target[0], order[target]))


def resolve(layout, names, own_snap=None):
    """`snap` or `snap.app` names -> [(snap, app)] of services, in the snap's order."""
    current = state_module.read(layout)
    found = []
    for name in names:
        snap, _, app = name.partition(".")
        if own_snap is not None and snap != own_snap:
            raise SnapError(f'unknown service: "{name}"')
        if snap not in current["snaps"]:
            raise SnapError(f'snap "{snap}" not found')
        services = daemons(snap_info(layout, snap))
        if app and app not in services:
            raise SnapError(f'snap "{snap}" has no service "{app}"')
        found.extend((snap, service) for service in ([app] if app else services))
    return found


def snap_info(layout, snap):
    import yaml
    revision = state_module.read(layout)["snaps"][snap]["revision"]
    return yaml.safe_load((layout.snap_mount(snap, revision) / "meta" / "snap.yaml").read_text())


def start(layout, snap, app, timeout=30.0):
    """Start the service (systemctl start) and return once its main process runs or it failed."""
    if is_active(layout, snap, app):
        return
    path = layout.service_status(snap, app)
    path.unlink(missing_ok=True)
    # The supervisor starts from a clean environment (as systemd's services do),
    # never inheriting the caller's cgroup marker.
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin")}
    for name in ["TURTLEBOT3C_BUILD_DIR", "TURTLEBOT3C_VENV", "SNAPSIM_PASSENV"] + \
            os.environ.get("SNAPSIM_PASSENV", "").split():
        if name in os.environ:
            env[name] = os.environ[name]
    subprocess.Popen([*COMMAND, "--root", str(layout.root), "_supervise", snap, app],
                     env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                     start_new_session=True, cwd="/")
    deadline = time.monotonic() + timeout
    while True:
        current = status(layout, snap, app) if path.exists() else {"state": "starting"}
        if current["state"] in ("active", "failed", "inactive") and path.exists():
            return
        if time.monotonic() > deadline:
            raise SnapError(f"timed out starting snap.{snap}.{app}.service")
        time.sleep(0.02)


def stop(layout, snap, app):
    """Stop the service (systemctl stop): returns when the whole stop sequence has run."""
    current = status(layout, snap, app)
    pid = current.get("supervisor")
    if not pid:
        return
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    app_info = snap_info(layout, snap)["apps"][app]
    stop_timeout = parse_duration(app_info.get("stop-timeout"), DEFAULT_STOP_TIMEOUT)
    deadline = time.monotonic() + 3 * stop_timeout + 15
    while supervisor_alive(pid):
        if time.monotonic() > deadline:
            raise SnapError(f"timed out stopping snap.{snap}.{app}.service")
        time.sleep(0.02)


def restart(layout, snap, app):
    stop(layout, snap, app)
    start(layout, snap, app)


def set_enabled(layout, snap, app, enabled):
    with state_module.locked(layout) as current:
        current["snaps"][snap]["services"][app]["enabled"] = enabled


def is_enabled(layout, snap, app):
    return state_module.read(layout)["snaps"][snap]["services"].get(app, {}).get("enabled", False)


def perform(layout, action, targets, enable=False, disable=False):
    """snap start/stop/restart on [(snap, app)], in the services' order (`after`/`before`):
    starts in it, stops in reverse; a restart stops all in reverse, then starts all in order."""
    if action not in ("start", "stop", "restart"):
        raise SnapError(f"unknown service action {action}")
    ordered = in_start_order(layout, targets)
    if action in ("stop", "restart"):
        for snap, app in reversed(ordered):
            if disable:
                set_enabled(layout, snap, app, False)
            stop(layout, snap, app)
    if action in ("start", "restart"):
        for snap, app in ordered:
            if enable:
                set_enabled(layout, snap, app, True)
            start(layout, snap, app)


def table(layout, targets):
    rows = [("Service", "Startup", "Current", "Notes")]
    for snap, app in sorted(targets):  # by name, as snapd lists them
        rows.append((f"{snap}.{app}", "enabled" if is_enabled(layout, snap, app) else "disabled",
                     "active" if is_active(layout, snap, app) else "inactive", "-"))
    widths = [max(len(row[column]) for row in rows) for column in range(4)]
    return "".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip() + "\n" for row in rows)
