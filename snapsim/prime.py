"""Build a snap's prime tree from snap/snapcraft.yaml, as snapcraft 7 does for core20.

What a real build would download or compile comes from this host instead:
- catkin parts: the install space tools/build made ($TURTLEBOT3C_BUILD_DIR/prime/opt/ros/noetic),
  copied, with its build-time path replaced by the one a snapcraft build would leave;
- stage-packages: the ROS executables of Debian's ROS 1 in /usr (found on PATH at run time);
- python parts: the packages of the host's Python (checked importable).
The rest is built as snapcraft builds it: dump parts with `organize`, the
ros1-noetic extension (command-chain, environment, roslaunch/rosrun wrappers),
snapcraft-runner first in every app's command-chain, hook wrappers in meta/hooks,
and meta/snap.yaml, which is all snapsim reads at run time.
"""
import fnmatch
import os
import platform
import shutil
import subprocess
from pathlib import Path

import yaml

from .state import SnapError

REPO = Path(__file__).resolve().parent.parent
SNAPCRAFT_BUILD_PREFIX = "/root/parts/workspace/install/opt/ros/noetic"

ARCHITECTURES = {  # uname -m -> (dpkg architecture, multiarch triplet)
    "x86_64": ("amd64", "x86_64-linux-gnu"),
    "aarch64": ("arm64", "aarch64-linux-gnu"),
    "armv7l": ("armhf", "arm-linux-gnueabihf"),
}

# The executables a stage-package gives apps, and who provides them here.
HOST_STAGE_PACKAGES = {
    "ros-noetic-roslaunch": ["roslaunch", "roscore"],
    "ros-noetic-rosbash": ["rosrun"],
}

# Keys snapcraft copies from an app in snapcraft.yaml to meta/snap.yaml.
APP_KEYS = (
    "command", "command-chain", "environment", "daemon", "stop-command", "post-stop-command", "stop-timeout",
    "start-timeout", "restart-condition", "restart-delay", "install-mode", "stop-mode", "refresh-mode",
    "plugs", "slots", "after", "before", "timer", "reload-command", "watchdog-timeout", "passthrough",
)

ROS1_NOETIC_ENVIRONMENT = {
    "ROS_VERSION": "1",
    "ROS_DISTRO": "noetic",
    "PYTHONPATH": "$SNAP/opt/ros/noetic/lib/python3.8/site-packages:$SNAP/usr/lib/python3/dist-packages:${PYTHONPATH}",
}
ROS1_LAUNCH = "snap/command-chain/ros1-launch"
RUNNER = "snap/command-chain/snapcraft-runner"


def host_architecture():
    machine = platform.machine()
    if machine not in ARCHITECTURES:
        raise SnapError(f"snapsim: unsupported machine {machine}")
    return ARCHITECTURES[machine]


def build_dir():
    return Path(os.environ.get("TURTLEBOT3C_BUILD_DIR", REPO / "build"))


def load_project(project_dir):
    path = Path(project_dir) / "snap" / "snapcraft.yaml"
    if not path.is_file():
        raise SnapError(f"cannot find {path}")
    project = yaml.safe_load(path.read_text())
    _, triplet = host_architecture()
    variables = {"SNAPCRAFT_ARCH_TRIPLET": triplet, "SNAPCRAFT_PROJECT_NAME": project["name"]}
    for key, value in project.items():
        if key not in ("name", "version"):
            project[key] = _substitute(value, variables)
    return project


def _substitute(value, variables):
    if isinstance(value, str):
        for name, replacement in variables.items():
            value = value.replace("${" + name + "}", replacement).replace("$" + name, replacement)
        return value
    if isinstance(value, list):
        return [_substitute(item, variables) for item in value]
    if isinstance(value, dict):
        return {key: _substitute(item, variables) for key, item in value.items()}
    return value


def build_prime(project_dir, prime, host_python):
    """Build the prime tree of the project in `project_dir` into `prime`; return meta/snap.yaml's content."""
    project_dir = Path(project_dir).resolve()
    project = load_project(project_dir)
    prime = Path(prime)
    prime.mkdir(parents=True)
    notes = []
    for name, part in project.get("parts", {}).items():
        plugin = part.get("plugin")
        builder = PART_BUILDERS.get(plugin)
        if builder is None:
            raise SnapError(f"snapsim: part {name}: plugin {plugin!r} is not supported")
        notes.extend(builder(name, part, project_dir, prime, host_python))
    apps = {name: _snap_yaml_app(app) for name, app in project.get("apps", {}).items()}
    if any("ros1-noetic" in app.get("extensions", []) for app in project.get("apps", {}).values()):
        _write_ros1_extension(prime)
    _write(prime / RUNNER, _runner_script(prime), 0o755)
    hooks = _write_hooks(project_dir, prime, project.get("hooks") or {})
    meta = {
        "name": project["name"],
        "version": str(project.get("version", "")),
        "summary": project.get("summary", ""),
        "description": project.get("description", ""),
        "base": project.get("base"),
        "confinement": project.get("confinement", "strict"),
        "grade": project.get("grade", "stable"),
        "architectures": [host_architecture()[0]],
        "apps": apps,
        "hooks": hooks,
    }
    if project.get("environment"):
        meta["environment"] = project["environment"]
    for key in ("plugs", "slots"):
        if project.get(key):
            meta[key] = project[key]
    _write(prime / "meta" / "snap.yaml", yaml.safe_dump(meta, sort_keys=False), 0o644)
    _write(prime / "meta" / "snapsim-host.txt",
           "Provided by the host instead of a snapcraft build:\n" + "".join(f"- {note}\n" for note in notes), 0o644)
    return meta


def _snap_yaml_app(app):
    """An app as snapcraft writes it to meta/snap.yaml: extension merged, runner first."""
    chain = list(app.get("command-chain", []))
    environment = dict(app.get("environment", {}))
    if "ros1-noetic" in app.get("extensions", []):
        chain = [ROS1_LAUNCH] + [entry for entry in chain if entry != ROS1_LAUNCH]
        for key, value in ROS1_NOETIC_ENVIRONMENT.items():
            environment.setdefault(key, value)
    result = {key: app[key] for key in APP_KEYS if key in app}
    if chain:
        result["adapter"] = "full"
    if result.get("adapter") != "none":
        chain = [RUNNER] + chain
    result["command-chain"] = chain
    if environment:
        result["environment"] = environment
    return result


# --- parts ---------------------------------------------------------------------------

def _catkin_part(name, part, project_dir, prime, host_python):
    install_space = build_dir() / "prime" / "opt" / "ros" / "noetic"
    if not (install_space / "setup.bash").is_file():
        raise SnapError(f"snapsim: part {name}: no catkin install space at {install_space}: run tools/build")
    for package in part.get("catkin-packages-ignore", []):
        if (install_space / "share" / package).exists():
            raise SnapError(f"snapsim: part {name}: {package} is ignored but built into {install_space}")
    target = prime / "opt" / "ros" / "noetic"
    shutil.copytree(install_space, target, symlinks=True)
    _replace_in_text_files(target, str(install_space), SNAPCRAFT_BUILD_PREFIX)
    notes = [f"part {name}: catkin install space copied from {install_space}"]
    return notes + _check_stage_packages(name, part)


def _check_stage_packages(name, part):
    notes = []
    for package in part.get("stage-packages", []):
        executables = HOST_STAGE_PACKAGES.get(package)
        if executables is None:
            raise SnapError(f"snapsim: part {name}: no host stand-in known for stage-package {package}")
        missing = [executable for executable in executables if not shutil.which(executable)]
        if missing:
            raise SnapError(f"snapsim: part {name}: stage-package {package} needs {', '.join(missing)} on this host")
        notes.append(f"part {name}: stage-package {package}: {', '.join(executables)} from the host's PATH")
    return notes


def _dump_part(name, part, project_dir, prime, host_python):
    source = (project_dir / part.get("source", ".")).resolve()
    if not source.is_dir():
        raise SnapError(f"snapsim: part {name}: no source folder {source}")
    files = sorted(path.relative_to(source) for path in source.rglob("*") if not path.is_dir())
    organize = part.get("organize", {})
    for relative in files:
        destination = _organized(str(relative), organize)
        target = prime / destination
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source / relative, target, follow_symlinks=False)
    return []


def _organized(relative, organize):
    """Where `organize` puts a file: `'glob': dir/` moves it into dir, `'name': other` renames it."""
    for pattern, destination in organize.items():
        if _glob_match(relative, pattern):
            if destination.endswith("/"):
                return destination + os.path.basename(relative)
            return destination
    return relative


def _glob_match(relative, pattern):
    """Glob matching as in a folder: `*` never crosses a `/`."""
    parts, pattern_parts = relative.split("/"), pattern.rstrip("/").split("/")
    return len(parts) == len(pattern_parts) and all(
        fnmatch.fnmatchcase(part, wanted) for part, wanted in zip(parts, pattern_parts))


def _python_part(name, part, project_dir, prime, host_python):
    notes = []
    for requirement in part.get("python-packages", []):
        distribution = requirement.split("=")[0].split("<")[0].split(">")[0].strip()
        module = distribution.replace("-", "_")
        found = subprocess.run([host_python, "-c", f"import {module}; print({module}.__file__)"],
                               capture_output=True, text=True)
        if found.returncode != 0:
            raise SnapError(f"snapsim: part {name}: {requirement} is not importable by {host_python}")
        notes.append(f"part {name}: {requirement} from the host's Python ({found.stdout.strip()})")
    return notes


def _nil_part(name, part, project_dir, prime, host_python):
    return _check_stage_packages(name, part)


PART_BUILDERS = {"catkin": _catkin_part, "dump": _dump_part, "python": _python_part, "nil": _nil_part}


def _replace_in_text_files(folder, old, new):
    for path in folder.rglob("*"):
        if path.is_symlink() or not path.is_file():
            continue
        data = path.read_bytes()
        if b"\0" in data or old.encode() not in data:
            continue
        mode = path.stat().st_mode
        path.write_bytes(data.replace(old.encode(), new.encode()))
        path.chmod(mode)


# --- generated files -----------------------------------------------------------------

def _write(path, text, mode):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    path.chmod(mode)


def _write_ros1_extension(prime):
    _write(prime / ROS1_LAUNCH, ROS1_LAUNCH_SCRIPT, 0o755)
    for tool in ("roslaunch", "rosrun"):
        _write(prime / tool, ROS_TOOL_WRAPPER.format(tool=tool), 0o755)


# Same behaviour as the extension's launch script in snapcraft 4.3-7.x: save the
# arguments (sourcing setup.bash may change them), activate the workspace, exec.
ROS1_LAUNCH_SCRIPT = """#!/bin/bash
# snapsim's rendering of snapcraft's ros1-noetic command-chain step.
activate_workspace() {
  local rosdir="$1"
  local setup_file="$rosdir/setup.bash"
  if [ ! -f "$setup_file" ]; then
    echo "error: $setup_file not found"
    exit 1
  fi
  _CATKIN_SETUP_DIR="$rosdir" source "$setup_file"
}

original_args=("$@")
activate_workspace "$SNAP/opt/ros/$ROS_DISTRO"
exec "${original_args[@]}"
"""

ROS_TOOL_WRAPPER = """#!/bin/sh
# snapsim's rendering of the ros1-noetic extension's {tool} wrapper (snapcraft 7.4+).
if [ -z "$SNAP" ]; then
  echo "Not running inside a snap context: SNAP not declared"
  exit 1
fi
exec {tool} "$@"
"""


def _library_lines(prime):
    _, triplet = host_architecture()
    candidates = ["lib", "usr/lib", f"lib/{triplet}", f"usr/lib/{triplet}"]
    existing = [f"$SNAP/{folder}" for folder in candidates if (prime / folder).is_dir()]
    lines = []
    if existing:
        lines.append('LD_LIBRARY_PATH="${LD_LIBRARY_PATH:+$LD_LIBRARY_PATH:}' + ":".join(existing) + '"')
    lines.append('export LD_LIBRARY_PATH="$SNAP_LIBRARY_PATH${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"')
    return lines


def _runner_script(prime):
    lines = ["#!/bin/sh", 'PATH="$SNAP/usr/sbin:$SNAP/usr/bin:$SNAP/sbin:$SNAP/bin${PATH:+:$PATH}"']
    return "\n".join(lines + _library_lines(prime) + ['exec "$@"', ""])


def _write_hooks(project_dir, prime, declared):
    hooks = {name: dict(value or {}) for name, value in declared.items()}
    hooks_source = project_dir / "snap" / "hooks"
    if hooks_source.is_dir():
        for hook in sorted(hooks_source.iterdir()):
            if hook.is_dir():
                continue
            (prime / "snap" / "hooks").mkdir(parents=True, exist_ok=True)
            shutil.copy2(hook, prime / "snap" / "hooks" / hook.name)
            lines = ["#!/bin/sh", 'PATH="$SNAP/usr/sbin:$SNAP/usr/bin:$SNAP/sbin:$SNAP/bin${PATH:+:$PATH}"']
            lines += _library_lines(prime) + [f'exec "$SNAP/snap/hooks/{hook.name}" "$@"', ""]
            _write(prime / "meta" / "hooks" / hook.name, "\n".join(lines), 0o755)
            hooks.setdefault(hook.name, {})
    return hooks
