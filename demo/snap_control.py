"""The `snap` command line the demo drives: snapsim in a private root, or the real `snap`.

Both offer the same few operations, so the demo's steps read like the guide
(`install`, `set`, `start --enable`, `stop`), whichever runs them.
"""
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

from snapsim.supervisor import root_processes

SNAP = "turtlebot3c"
REPO = Path(__file__).resolve().parent.parent
SNAPSIM = Path(sys.prefix) / "bin" / "snapsim"  # installed by tools/setup-env beside this python3
SERVICES = ("core", "teleop", "mapping", "navigation")
# Where the snap keeps its maps: $SNAP_COMMON/maps, or (before that) the services' $SNAP_USER_COMMON/map.
MAP_DIRS = (f"/var/snap/{SNAP}/common/maps", f"/root/snap/{SNAP}/common/map")


class SnapCommandError(RuntimeError):
    pass


class SnapCommandLine:
    """What the demo needs of `snap`; `argv_prefix` is the command before the subcommand."""

    def __init__(self, argv_prefix, env=None):
        self.argv_prefix = list(argv_prefix)
        self.env = env

    def run(self, *args, check=True, timeout=600):
        argv = self.argv_prefix + [str(arg) for arg in args]
        done = subprocess.run(argv, env=self.env, capture_output=True, text=True, timeout=timeout)
        if check and done.returncode != 0:
            raise SnapCommandError(f"`{' '.join(argv)}` failed ({done.returncode}):\n{done.stdout}{done.stderr}")
        return done

    def set(self, **values):
        return self.run("set", SNAP, *[f"{key.replace('_', '-')}={value}" for key, value in values.items()])

    def get(self):
        return json.loads(self.run("get", "-d", SNAP).stdout)

    def start(self, app, enable=False):
        return self.run("start", *(["--enable"] if enable else []), f"{SNAP}.{app}")

    def stop(self, app, disable=False):
        return self.run("stop", *(["--disable"] if disable else []), f"{SNAP}.{app}")

    def restart(self, *apps):
        return self.run("restart", *[f"{SNAP}.{app}" for app in apps])

    def logs(self, lines="all"):
        done = self.run("logs", "-n", lines, SNAP, check=False)
        return done.stdout + done.stderr

    def current_map(self):
        """The installed current_map.yaml (in the first map folder that has one), or None."""
        for folder in self.map_dirs:
            if (folder / "current_map.yaml").exists():
                return folder / "current_map.yaml"
        return None

    def active_services(self):
        """Names of the snap's services that are active now."""
        table = self.run("services", SNAP).stdout.splitlines()[1:]
        return {row.split()[0].split(".", 1)[1] for row in table if len(row.split()) >= 3
                and row.split()[2] == "active"}


class Snapsim(SnapCommandLine):
    """snapsim with all its state under `root`; daemons use the master at `master_uri`.

    The master's URI goes to the root's /etc/environment, as an owner would set a
    non-default one; the snap's ROS network chain keeps a URI given on purpose.
    """

    kind = "snapsim"

    def __init__(self, root, master_uri, env):
        self.root = Path(root)
        (self.root / "etc").mkdir(parents=True, exist_ok=True)
        (self.root / "etc" / "environment").write_text(
            f"ROS_MASTER_URI={master_uri}\nROS_HOSTNAME=localhost\n")
        super().__init__([str(SNAPSIM), "--root", str(self.root)], env)

    def install(self, project_dir):
        return self.run("install", project_dir, "--dangerous").stdout.strip()

    @property
    def map_dirs(self):
        return [self.root / folder.lstrip("/") for folder in MAP_DIRS]

    def finish(self):
        """Remove the snap (its services stop) and make sure nothing of this root runs on."""
        self.run("remove", "--purge", SNAP, check=False)
        for pid in root_processes(self.root):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        shutil.rmtree(self.root, ignore_errors=True)


class RealSnap(SnapCommandLine):
    """The real `snap` (run as root, e.g. in CI's Ubuntu 20.04 container); the master is the snap's default."""

    kind = "snap"

    def __init__(self, snap_file, env):
        if os.geteuid() != 0:
            raise SnapCommandError("--snap-cli snap drives snapd's services and reads root's maps: run it as root")
        if shutil.which("snap") is None:
            raise SnapCommandError("--snap-cli snap: there is no `snap` command on this machine")
        self.snap_file = snap_file
        super().__init__(["snap"], env)

    def install(self, project_dir):
        if not self.snap_file:
            raise SnapCommandError("--snap-cli snap needs --snap-file PATH (the .snap that snapcraft built)")
        return self.run("install", self.snap_file, "--dangerous").stdout.strip()

    @property
    def map_dirs(self):
        return [Path(folder) for folder in MAP_DIRS]

    def finish(self):
        for app in SERVICES:
            self.run("stop", f"{SNAP}.{app}", check=False)
        self.run("stop", "--disable", f"{SNAP}.navigation", check=False)
