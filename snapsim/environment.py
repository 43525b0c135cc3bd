"""The environment and argv snapd gives an app, a service command or a hook.

Follows snapd's snap-exec: the process environment, then snapd's variables
(SNAP, SNAP_DATA, SNAP_USER_DATA, HOME=SNAP_USER_DATA ...), then the snap's and
the app's `environment:` entries, each expanded against what came before; the
command split on spaces, its arguments expanded (those that expand to nothing
dropped), and the command-chain in front. Services and hooks run as root with
systemd's environment plus /etc/environment; `snap run` keeps the caller's.
All paths point into the state root.
"""
import os
import re
import sys
from pathlib import Path

from . import prime as prime_module
from .layout import current_user, root_user
from .state import SnapError

SYSTEM_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
SNAP_LIBRARY_PATH = "/var/lib/snapd/lib/gl:/var/lib/snapd/lib/gl32:/var/lib/snapd/void"
_VARIABLE = re.compile(r"\$\{([^}]*)\}|\$([A-Za-z0-9_]+)")
COMMANDS = {"": "command", "stop": "stop-command", "post-stop": "post-stop-command", "reload": "reload-command"}


def expand(text, env):
    """Expand $NAME and ${NAME} like Go's os.Expand: unknown names become ""."""
    return _VARIABLE.sub(lambda match: env.get(match.group(1) or match.group(2), ""), text)


def host_python_bin():
    """The folder of the Python standing in for the base snap's python3: the virtualenv snapsim runs in
    (.venv/bin/snapsim runs in it), or None outside one (the apps find python3 on their PATH)."""
    if sys.prefix == sys.base_prefix:
        return None
    return Path(sys.prefix) / "bin"


def base_path(layout, rest):
    python_bin = host_python_bin()
    parts = [str(layout.base_bin)] + ([str(python_bin)] if python_bin else []) + [rest]
    return ":".join(parts)


def read_environment_file(path):
    env = {}
    if not path.is_file():
        return env
    for line in path.read_text().splitlines():
        line = line.strip()
        if not line or line.startswith("#") or "=" not in line:
            continue
        key, value = line.split("=", 1)
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":
            value = value[1:-1]
        env[key.strip()] = value
    return env


def system_environment(layout):
    """What systemd gives services (and snapd gives hooks): a fixed PATH, LANG, /etc/environment.

    Variables named in $SNAPSIM_PASSENV are passed through too (test harness markers).
    """
    env = {"PATH": SYSTEM_PATH, "LANG": "C.UTF-8"}
    env.update(read_environment_file(layout.etc_environment))
    for name in os.environ.get("SNAPSIM_PASSENV", "").split():
        if name in os.environ:
            env[name] = os.environ[name]
    env["PATH"] = base_path(layout, env["PATH"])
    return env


def caller_environment(layout):
    env = dict(os.environ)
    env["PATH"] = base_path(layout, env.get("PATH", SYSTEM_PATH))
    return env


def snapd_variables(layout, snap_info, revision, user, app_name=None):
    name = snap_info["name"]
    mount = layout.snap_mount(name, revision)
    user_data = layout.user_snap_dir(user, name) / revision
    user_common = layout.user_snap_dir(user, name) / "common"
    arch, _ = prime_module.host_architecture()
    env = {
        "SNAP": str(mount),
        "SNAP_COMMON": str(layout.snap_common(name)),
        "SNAP_DATA": str(layout.snap_data(name, revision)),
        "SNAP_NAME": name,
        "SNAP_INSTANCE_NAME": name,
        "SNAP_INSTANCE_KEY": "",
        "SNAP_VERSION": str(snap_info.get("version", "")),
        "SNAP_REVISION": revision,
        "SNAP_ARCH": arch,
        "SNAP_LIBRARY_PATH": SNAP_LIBRARY_PATH,
        "SNAP_REEXEC": "",
        "SNAP_UID": str(user.pw_uid),
        "SNAP_EUID": str(user.pw_uid),
        "SNAP_USER_DATA": str(user_data),
        "SNAP_USER_COMMON": str(user_common),
        "SNAP_REAL_HOME": str(layout.home(user)),
        "HOME": str(user_data),
        "XDG_RUNTIME_DIR": str(layout.runtime_dir(user.pw_uid, name)),
    }
    if app_name is not None:
        env["SNAP_APP_NAME"] = app_name
    return env


def create_user_dirs(layout, snap, revision, user):
    """What `snap run` creates: ~/snap (0700), SNAP_USER_DATA, SNAP_USER_COMMON, the `current` link."""
    snap_home = layout.home(user) / "snap"
    snap_home.mkdir(parents=True, exist_ok=True)
    snap_home.chmod(0o700)
    user_dir = snap_home / snap
    for folder in (user_dir / revision, user_dir / "common"):
        folder.mkdir(parents=True, exist_ok=True)
        folder.chmod(0o755)
    current = user_dir / "current"
    if os.path.lexists(current) and os.readlink(current) != revision:
        current.unlink()
    if not os.path.lexists(current):
        current.symlink_to(revision)
    layout.runtime_dir(user.pw_uid, snap).mkdir(parents=True, exist_ok=True)


def extend_with_expanded(env, entries):
    for key, value in (entries or {}).items():
        env[key] = expand(str(value), env)
    return env


def app_command(layout, snap_info, revision, app_name, command="", extra_args=(), service=False, cookie=""):
    """(argv, env, cwd) for running an app's command ("" / "stop" / "post-stop" / "shell")."""
    apps = snap_info.get("apps", {})
    if app_name not in apps:
        raise SnapError(f'snap "{snap_info["name"]}" has no app "{app_name}"')
    app = apps[app_name]
    user = root_user() if service else current_user()
    env = system_environment(layout) if service else caller_environment(layout)
    env.update(snapd_variables(layout, snap_info, revision, user, app_name))
    env["SNAP_COOKIE"] = cookie
    extend_with_expanded(env, snap_info.get("environment"))
    extend_with_expanded(env, app.get("environment"))
    create_user_dirs(layout, snap_info["name"], revision, user)

    mount = env["SNAP"]
    if command == "shell":
        argv = ["/bin/bash"]
    else:
        key = COMMANDS.get(command)
        if key is None or key not in app:
            raise SnapError(f'no {key or command} for app "{app_name}"')
        words = app[key].split(" ")
        args = [value for value in (expand(word, env) for word in words[1:]) if value != ""]
        argv = [f"{mount}/{words[0]}"] + args
    chain = [f"{mount}/{entry}" for entry in app.get("command-chain", [])]
    cwd = env["SNAP_DATA"] if service else os.getcwd()
    return chain + argv + list(extra_args), env, cwd


def hook_command(layout, snap_info, revision, hook_name, cookie):
    """(argv, env, cwd) for running a hook: as root, with snapd's environment."""
    hook = (snap_info.get("hooks") or {}).get(hook_name) or {}
    user = root_user()
    env = system_environment(layout)
    env.update(snapd_variables(layout, snap_info, revision, user))
    env["SNAP_COOKIE"] = cookie
    env["SNAP_CONTEXT"] = cookie
    extend_with_expanded(env, snap_info.get("environment"))
    extend_with_expanded(env, hook.get("environment"))
    create_user_dirs(layout, snap_info["name"], revision, user)
    mount = env["SNAP"]
    chain = [f"{mount}/{entry}" for entry in hook.get("command-chain", [])]
    return chain + [f"{mount}/meta/hooks/{hook_name}"], env, env["SNAP_DATA"]
