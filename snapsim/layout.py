"""Where a snapsim system keeps everything: one state root, standing in for `/`.

snapd's paths (/snap, /var/snap, /root, /home/<user>, /var/lib/snapd, /run)
are mapped into the root, so several simulated systems run side by side and
nothing is written elsewhere.
"""
import os
import pwd
from pathlib import Path


class Layout:
    def __init__(self, root):
        self.root = Path(root).resolve()

    def under(self, absolute):
        """The place inside the root standing for the absolute path `absolute`."""
        return self.root / str(absolute).lstrip("/")

    # --- snapd's own state -----------------------------------------------------------
    @property
    def state_dir(self):
        return self.under("/var/lib/snapsim")

    @property
    def state_file(self):
        return self.state_dir / "state.json"

    @property
    def lock_file(self):
        return self.state_dir / "state.lock"

    @property
    def contexts_dir(self):
        return self.state_dir / "contexts"

    @property
    def snapshots_dir(self):
        return self.state_dir / "snapshots"

    @property
    def journal(self):
        return self.under("/var/log/snapsim/journal.jsonl")

    @property
    def etc_environment(self):
        """Read by daemons and hooks, as systemd's EnvironmentFile=-/etc/environment."""
        return self.under("/etc/environment")

    @property
    def base_bin(self):
        """Stands for the base snap's /usr/bin: where `snapctl` is found."""
        return self.under("/usr/bin")

    def service_status(self, snap, app):
        return self.under(f"/run/snapsim/services/snap.{snap}.{app}.json")

    # --- a snap's paths --------------------------------------------------------------
    def snap_mount(self, snap, revision):
        return self.under(f"/snap/{snap}/{revision}")

    def snap_dir(self, snap):
        return self.under(f"/snap/{snap}")

    def data_dir(self, snap):
        return self.under(f"/var/snap/{snap}")

    def snap_data(self, snap, revision):
        return self.under(f"/var/snap/{snap}/{revision}")

    def snap_common(self, snap):
        return self.under(f"/var/snap/{snap}/common")

    def home(self, user):
        """The home of `user` (a pwd entry) inside the root."""
        return self.under(user.pw_dir)

    def user_snap_dir(self, user, snap):
        return self.home(user) / "snap" / snap

    def all_homes(self):
        """Every home a snap may have left user data in: /root and /home/* in the root."""
        homes = [self.under("/root")]
        home_base = self.under("/home")
        if home_base.is_dir():
            homes.extend(sorted(home_base.iterdir()))
        return homes

    def runtime_dir(self, uid, snap):
        return self.under(f"/run/user/{uid}/snap.{snap}")


def root_user():
    return pwd.getpwuid(0)


def current_user():
    return pwd.getpwuid(os.getuid())
