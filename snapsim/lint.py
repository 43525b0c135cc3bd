"""Checks of a prime tree the store's review tools make (a subset that matters here).

- every command, stop-command, post-stop-command, reload-command (first word)
  and every command-chain entry exists in the snap and is executable;
- every meta/hooks file is executable and has a name snapd knows;
- keys that only make sense for services appear only on daemons;
- durations are well formed;
- no symlink points outside the snap.
"""
import os
import re
from pathlib import Path

import yaml

KNOWN_HOOKS = {"install", "configure", "default-configure", "remove", "pre-refresh", "post-refresh",
               "prepare-device", "check-health", "gate-auto-refresh", "install-device", "fde-setup"}
KNOWN_HOOK_PATTERNS = [re.compile(rf"^{kind}-(plug|slot)-[-a-z0-9]+$")
                       for kind in ("prepare", "unprepare", "connect", "disconnect")]
DAEMON_ONLY_KEYS = {"after", "before", "bus-name", "daemon-scope", "install-mode", "ports", "post-stop-command",
                    "refresh-mode", "reload-command", "restart-condition", "restart-delay", "sockets",
                    "start-timeout", "stop-command", "stop-mode", "stop-timeout", "timer", "watchdog-timeout"}
DURATION_KEYS = ("stop-timeout", "start-timeout", "restart-delay", "watchdog-timeout")
DURATION = re.compile(r"^[0-9]+(ns|us|ms|s|m)?$")
COMMAND_KEYS = ("command", "stop-command", "post-stop-command", "reload-command")


def lint(prime):
    prime = Path(prime)
    snap = yaml.safe_load((prime / "meta" / "snap.yaml").read_text())
    problems = []
    for name, app in snap.get("apps", {}).items():
        for key in COMMAND_KEYS:
            if key in app:
                problems += _executable(prime, app[key].split(" ")[0], f"app {name}: {key}")
        for entry in app.get("command-chain", []):
            problems += _executable(prime, entry, f"app {name}: command-chain")
        if "daemon" not in app:
            problems += [f"app {name}: {key} is only for daemons" for key in sorted(DAEMON_ONLY_KEYS & set(app))]
        for key in DURATION_KEYS:
            if key in app and not DURATION.match(str(app[key])):
                problems.append(f"app {name}: {key} {app[key]!r} is not a duration like 30s")
    for name, hook in (snap.get("hooks") or {}).items():
        if name not in KNOWN_HOOKS and not any(pattern.match(name) for pattern in KNOWN_HOOK_PATTERNS):
            problems.append(f"hook {name}: unknown hook name")
        problems += _executable(prime, f"meta/hooks/{name}", f"hook {name}")
        for entry in (hook or {}).get("command-chain", []):
            problems += _executable(prime, entry, f"hook {name}: command-chain")
    problems += _external_symlinks(prime)
    return problems


def _executable(prime, relative, what):
    path = prime / relative
    if relative.startswith("/") or not path.is_file():
        return [f"{what}: {relative} is not a file in the snap"]
    if not os.access(path, os.X_OK):
        return [f"{what}: {relative} is not executable"]
    return []


def _external_symlinks(prime):
    """Symlinks whose target leaves the snap (absolute targets always do: they name the host's files)."""
    problems = []
    root = os.path.abspath(prime)
    for folder, dirs, files in os.walk(root):
        for entry in dirs + files:
            path = os.path.join(folder, entry)
            if not os.path.islink(path):
                continue
            target = os.readlink(path)
            resolved = os.path.normpath(os.path.join(folder, target))
            if os.path.isabs(target) or not resolved.startswith(root + os.sep):
                problems.append(f"{os.path.relpath(path, root)}: symlink to {target} points outside the snap")
    return problems
