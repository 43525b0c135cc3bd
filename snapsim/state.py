"""snapd's state: installed snaps, their configuration and services, under a lock.

One JSON file, read and written under an exclusive flock, so concurrent
snapsim processes (the CLI, snapctl in hooks and daemons, supervisors) agree.
"""
import contextlib
import fcntl
import json
import os


@contextlib.contextmanager
def locked(layout):
    """Yield the state (a dict) under the lock; it is saved when the block ends without error."""
    layout.state_dir.mkdir(parents=True, exist_ok=True)
    with open(layout.lock_file, "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        state = read(layout)
        yield state
        write(layout, state)


def read(layout):
    try:
        with open(layout.state_file) as stream:
            return json.load(stream)
    except FileNotFoundError:
        return {"snaps": {}}


def write(layout, state):
    temporary = layout.state_file.with_suffix(".tmp")
    with open(temporary, "w") as stream:
        json.dump(state, stream, indent=1, sort_keys=True)
    os.replace(temporary, layout.state_file)


def snap_state(state, snap):
    try:
        return state["snaps"][snap]
    except KeyError:
        raise SnapError(f'snap "{snap}" is not installed') from None


class SnapError(Exception):
    """An error `snap` would report as `error: <message>` with exit status 1."""
