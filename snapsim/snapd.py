"""`snap install`, refresh (installing over an installed snap) and `snap remove`, in snapd's order.

First install: mount (the prime tree at /snap/<name>/x<N>), data folders,
install hook, services start (except install-mode: disable), configure hook.
Refresh: pre-refresh hook, services stop, new revision with a copy of the
old data, post-refresh hook, services start, configure hook. A failing hook
undoes the change. Remove: services stop, remove hook (errors ignored), data
saved as a snapshot (unless --purge), then every trace of the snap deleted.
"""
import os
import secrets
import shlex
import shutil
import sys

import yaml

from . import hooks, prime, services
from . import state as state_module
from .environment import host_python_bin
from .state import SnapError

AUTO_CONNECT = {"network", "network-bind", "home", "opengl", "x11", "wayland", "desktop", "audio-playback"}


def ensure_system(layout):
    """The base snap's snapctl, pointing back at this snapsim root; rewritten when an earlier snapsim
    wrote another (so an install mends a system whose snapctl called a command snapsim no longer has)."""
    snapctl = layout.base_bin / "snapctl"
    command = " ".join(shlex.quote(str(word)) for word in (*services.SNAPCTL_COMMAND, layout.root))
    script = f'#!/bin/sh\n# snapctl of this snapsim system\nexec {command} "$@"\n'
    if not snapctl.exists() or snapctl.read_text() != script:
        snapctl.parent.mkdir(parents=True, exist_ok=True)
        snapctl.write_text(script)
        snapctl.chmod(0o755)
    layout.state_dir.mkdir(parents=True, exist_ok=True)


def host_python():
    python_bin = host_python_bin()
    return str(python_bin / "python3") if python_bin else sys.executable


def install(layout, project_dir, dangerous=False):
    ensure_system(layout)
    if not dangerous:
        raise SnapError(f'cannot find signatures with metadata for snap "{project_dir}" (use --dangerous)')
    name = prime.load_project(project_dir)["name"]
    existing = state_module.read(layout)["snaps"].get(name)
    number = 1 + (int(existing["revision"].lstrip("x")) if existing else 0)
    while layout.snap_mount(name, f"x{number}").exists():
        number += 1
    revision = f"x{number}"
    mount = layout.snap_mount(name, revision)
    try:
        info = prime.build_prime(project_dir, mount, host_python())
        services.daemons(info)  # snapd refuses a snap whose after/before name no service or make a cycle
    except BaseException:
        shutil.rmtree(mount, ignore_errors=True)
        raise
    if existing:
        _refresh(layout, name, info, existing, revision)
    else:
        _first_install(layout, name, info, revision)
    return f"{name} {info.get('version', '')} installed"


def _plugs(info):
    plugs = set(info.get("plugs") or {})
    for holder in list(info.get("apps", {}).values()) + list((info.get("hooks") or {}).values()):
        plugs.update((holder or {}).get("plugs", []))
    return sorted(plugs)


def _first_install(layout, name, info, revision):
    layout.snap_data(name, revision).mkdir(parents=True, exist_ok=True)
    layout.snap_common(name).mkdir(parents=True, exist_ok=True)
    _point_current(layout, name, revision)
    with state_module.locked(layout) as current:
        current["snaps"][name] = {
            "revision": revision, "config": {}, "cookie": secrets.token_hex(16),
            "services": {app: {"enabled": False} for app in services.daemons(info)},
            "connections": {plug: plug in AUTO_CONNECT for plug in _plugs(info)},
        }
    try:
        hooks.run_hook(layout, name, "install")
        for app in services.daemons(info):
            if info["apps"][app].get("install-mode") == "disable" and not services.is_active(layout, name, app):
                continue
            services.set_enabled(layout, name, app, True)
            services.start(layout, name, app)
        hooks.run_hook(layout, name, "configure")
    except BaseException:
        _stop_all(layout, name, info)
        _delete_everything(layout, name)
        raise


def _refresh(layout, name, info, existing, revision):
    old = existing["revision"]
    old_info = services.snap_info(layout, name)
    hooks.run_hook(layout, name, "pre-refresh")
    was_active = [app for app in services.daemons(old_info) if services.is_active(layout, name, app)]
    _stop_all(layout, name, old_info)
    shutil.copytree(layout.snap_data(name, old), layout.snap_data(name, revision), symlinks=True)
    for home in layout.all_homes():
        user_data = home / "snap" / name / old
        if user_data.is_dir():
            shutil.copytree(user_data, home / "snap" / name / revision, symlinks=True)
            _relink(home / "snap" / name / "current", revision)
    _point_current(layout, name, revision)
    with state_module.locked(layout) as current:
        snap_state = current["snaps"][name]
        snap_state["revision"] = revision
        for app in services.daemons(info):
            if app not in snap_state["services"]:
                snap_state["services"][app] = {"enabled": info["apps"][app].get("install-mode") != "disable"}
        for plug in _plugs(info):
            snap_state["connections"].setdefault(plug, plug in AUTO_CONNECT)
    try:
        hooks.run_hook(layout, name, "post-refresh")
        for app in services.daemons(info):
            if services.is_enabled(layout, name, app) or app in was_active:
                services.start(layout, name, app)
        hooks.run_hook(layout, name, "configure")
    except BaseException:
        _undo_refresh(layout, name, info, old_info, old, revision, was_active)
        raise


def _undo_refresh(layout, name, info, old_info, old, revision, was_active):
    """A failed post-refresh or configure hook: back to the old revision, as snapd undoes the change."""
    _stop_all(layout, name, info)
    _point_current(layout, name, old)
    for home in layout.all_homes():
        if (home / "snap" / name / old).is_dir():
            _relink(home / "snap" / name / "current", old)
        shutil.rmtree(home / "snap" / name / revision, ignore_errors=True)
    with state_module.locked(layout) as current:
        current["snaps"][name]["revision"] = old
    shutil.rmtree(layout.snap_data(name, revision), ignore_errors=True)
    shutil.rmtree(layout.snap_mount(name, revision), ignore_errors=True)
    for app in services.daemons(old_info):
        if services.is_enabled(layout, name, app) or app in was_active:
            services.start(layout, name, app)


def remove(layout, name, purge=False):
    current = state_module.read(layout)
    if name not in current["snaps"]:
        raise SnapError(f'snap "{name}" is not installed')
    info = services.snap_info(layout, name)
    _stop_all(layout, name, info)
    try:
        hooks.run_hook(layout, name, "remove")
    except SnapError:
        pass  # snapd ignores a failing remove hook
    message = f"{name} removed"
    if not purge:
        snapshot = layout.snapshots_dir / f"{name}-{current['snaps'][name]['revision']}-{secrets.token_hex(4)}"
        snapshot.mkdir(parents=True)
        if layout.data_dir(name).is_dir():
            shutil.copytree(layout.data_dir(name), snapshot / "system", symlinks=True)
        for home in layout.all_homes():
            if (home / "snap" / name).is_dir():
                shutil.copytree(home / "snap" / name, snapshot / "user" / home.name, symlinks=True)
        message += " (snap data snapshot saved)"
    _delete_everything(layout, name)
    return message


def _stop_all(layout, name, info):
    for app in reversed(services.daemons(info)):  # the reverse of the start order
        services.stop(layout, name, app)


def _delete_everything(layout, name):
    shutil.rmtree(layout.snap_dir(name), ignore_errors=True)
    shutil.rmtree(layout.data_dir(name), ignore_errors=True)
    for home in layout.all_homes():
        shutil.rmtree(home / "snap" / name, ignore_errors=True)
    status_dir = layout.under("/run/snapsim/services")
    if status_dir.is_dir():
        for path in status_dir.glob(f"snap.{name}.*"):
            path.unlink()
    run_user = layout.under("/run/user")
    if run_user.is_dir():
        for runtime in run_user.glob(f"*/snap.{name}"):
            shutil.rmtree(runtime, ignore_errors=True)
    for log in (layout.state_dir / "hook-logs").glob(f"{name}.*"):
        log.unlink()
    with state_module.locked(layout) as current:
        current["snaps"].pop(name, None)


def _point_current(layout, name, revision):
    _relink(layout.snap_dir(name) / "current", revision)
    _relink(layout.data_dir(name) / "current", revision)


def _relink(link, target):
    link.parent.mkdir(parents=True, exist_ok=True)
    temporary = link.with_name(f".{link.name}.tmp")
    if os.path.lexists(temporary):
        temporary.unlink()
    temporary.symlink_to(target)
    os.replace(temporary, link)


# --- interfaces (bookkeeping only: nothing is confined here) ------------------------

def connections(layout, name=None):
    rows = [("Interface", "Plug", "Slot", "Notes")]
    for snap, snap_state in sorted(state_module.read(layout)["snaps"].items()):
        if name and snap != name:
            continue
        for plug, connected in sorted(snap_state.get("connections", {}).items()):
            rows.append((plug, f"{snap}:{plug}", f":{plug}" if connected else "-", "-"))
    widths = [max(len(row[column]) for row in rows) for column in range(4)]
    return "".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip() + "\n" for row in rows)


def connect(layout, plug_ref, connected=True):
    snap, _, plug = plug_ref.partition(":")
    with state_module.locked(layout) as current:
        snap_connections = state_module.snap_state(current, snap).get("connections", {})
        if plug not in snap_connections:
            raise SnapError(f'snap "{snap}" has no plug named "{plug}"')
        snap_connections[plug] = connected


def snap_yaml(layout, name):
    revision = state_module.read(layout)["snaps"][name]["revision"]
    return yaml.safe_load((layout.snap_mount(name, revision) / "meta" / "snap.yaml").read_text())
