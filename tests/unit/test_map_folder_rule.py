"""The snap's rule for the current map (snap/local/map_folder.sh, snap/hooks/configure), in the shells that run
it: which map is "latest", and the configure hook against a `maps remove` running at the same time (issue #18
item 3 and the two cases found with it). Plain sh against a temporary folder and a stand-in snapctl; no build."""
import os
import shutil
import subprocess
import textwrap
import threading
from pathlib import Path

import pytest

from turtlebot3c_maps.map_store import MapStore

REPOSITORY = Path(__file__).resolve().parents[2]
MAP_FOLDER_SH = REPOSITORY / "snap" / "local" / "map_folder.sh"
CONFIGURE = REPOSITORY / "snap" / "hooks" / "configure"
SHELLS = [shell for shell in ("dash", "bash") if shutil.which(shell)]
SECOND = 1_700_000_000 * 10 ** 9  # a whole second, in ns


def add_map(folder, name, mtime_ns=None, image=True):
    (folder / f"{name}.yaml").write_text(f"image: {name}.pgm\n")
    if image:
        (folder / f"{name}.pgm").write_bytes(b"P5\n1 1\n255\n\x00")
        if mtime_ns is not None:
            os.utime(folder / f"{name}.pgm", ns=(mtime_ns, mtime_ns))


def newest(folder, shell):
    done = subprocess.run([shell, "-c", f'. "{MAP_FOLDER_SH}"; newest_map'], env=dict(os.environ, maps_dir=str(folder)),
                          capture_output=True, text=True, timeout=30, check=True)
    return done.stdout.strip()


@pytest.fixture
def maps(tmp_path):
    folder = tmp_path / "maps"
    folder.mkdir()
    return folder


@pytest.mark.parametrize("shell", SHELLS)
def test_latest_is_never_a_map_without_its_image_whatever_their_order(maps, shell):
    add_map(maps, "a-broken", image=False)
    add_map(maps, "b-linked", SECOND + 3)
    (maps / "b-linked.pgm").unlink()
    os.symlink("c-good.pgm", maps / "b-linked.pgm")
    add_map(maps, "c-good", SECOND)
    assert newest(maps, shell) == "c-good"
    (maps / "c-good.pgm").unlink()
    assert newest(maps, shell) == ""


@pytest.mark.parametrize("shell", SHELLS)
def test_latest_tells_maps_of_one_second_apart_by_their_nanoseconds(maps, shell):
    add_map(maps, "a", SECOND + 100)
    add_map(maps, "b", SECOND + 300_000_000)
    add_map(maps, "c", SECOND + 200_000_000)
    assert newest(maps, shell) == "b"


@pytest.mark.parametrize("shell", SHELLS)
def test_latest_of_maps_dated_alike_is_the_name_that_sorts_last(maps, shell):
    add_map(maps, "2026-11-21_14-05-09", SECOND)
    add_map(maps, "2026-11-21_14-05-09_2", SECOND)
    add_map(maps, "2026-11-21_14-05-08", SECOND)
    assert newest(maps, shell) == "2026-11-21_14-05-09_2"


@pytest.mark.parametrize("shell", SHELLS)
def test_files_in_transit_hidden_files_and_the_link_are_never_latest(maps, shell):
    add_map(maps, "kept", SECOND)
    add_map(maps, "new_map", SECOND + 5)
    add_map(maps, ".hidden", SECOND + 5)
    os.symlink("kept.yaml", maps / "current_map.yaml")
    assert newest(maps, shell) == "kept"


# --- the configure hook and the maps app's lock --------------------------------------------------

FAKE_SNAPCTL = textwrap.dedent("""\
    #!/bin/sh
    # snapctl for the configure hook: options are files in $FAKE_SNAPCTL/options, no service runs.
    case "$1" in
      get) cat "$FAKE_SNAPCTL/options/$2" 2>/dev/null || true ;;
      set) printf '%s' "${2#*=}" >"$FAKE_SNAPCTL/options/${2%%=*}" ;;
      services) printf 'Service Startup Current Notes\\n%s enabled inactive -\\n' "$2" ;;
      restart) echo "$2" >>"$FAKE_SNAPCTL/restarts" ;;
    esac
    """)
OPTIONS = {"simulation": "false", "turtlebot3-model": "burger", "lds-model": "LDS-01",
           "ros-master-host": "localhost", "opencr-port": "/dev/ttyACM0", "lds-port": "/dev/ttyUSB0"}


@pytest.fixture
def snap(tmp_path):
    """A snap's folders with map_folder.sh where the hook sources it, and a stand-in snapctl on PATH."""
    root = tmp_path / "snap"
    (root / "usr" / "bin").mkdir(parents=True)
    shutil.copy(MAP_FOLDER_SH, root / "usr" / "bin" / "map_folder.sh")
    tools = tmp_path / "tools"
    (tools / "options").mkdir(parents=True)
    (tools / "snapctl").write_text(FAKE_SNAPCTL)
    (tools / "snapctl").chmod(0o755)
    for key, value in OPTIONS.items():
        (tools / "options" / key).write_text(value)
    common = tmp_path / "common"
    (common / "maps").mkdir(parents=True)
    env = dict(os.environ, SNAP=str(root), SNAP_COMMON=str(common), SNAP_DATA=str(tmp_path / "data"),
               SNAP_INSTANCE_NAME="turtlebot3c", FAKE_SNAPCTL=str(tools), PATH=f"{tools}:{os.environ['PATH']}")
    return env, tools / "options", common / "maps"


def configure(env):
    return subprocess.Popen(["sh", str(CONFIGURE)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_choosing_a_map_waits_for_a_remove_under_way_and_never_points_at_a_removed_map(snap):
    env, options, folder = snap
    add_map(folder, "kept", SECOND)
    add_map(folder, "doomed", SECOND - 10 ** 9)
    os.symlink("kept.yaml", folder / "current_map.yaml")
    store = MapStore(folder)
    (options / "map").write_text("doomed")
    with store.changing():  # `turtlebot3c.maps remove doomed`, which has just seen doomed is not current
        assert store.current_name() == "kept"
        hook = configure(env)  # `snap set turtlebot3c map=doomed` meanwhile
        finished = threading.Event()
        threading.Thread(target=lambda: (hook.wait(), finished.set()), daemon=True).start()
        finished.wait(2.0)
        store.remove("doomed")
    stdout, stderr = hook.communicate(timeout=30)
    assert os.path.exists(folder / "current_map.yaml"), "current_map.yaml names a removed map"
    assert hook.returncode == 1 and "there is no map 'doomed'; known maps: kept" in stderr
    assert os.readlink(folder / "current_map.yaml") == "kept.yaml"


def test_a_chosen_map_without_its_image_is_refused_and_latest_skips_it(snap):
    env, options, folder = snap
    add_map(folder, "good", SECOND)
    add_map(folder, "broken", image=False)
    (options / "map").write_text("broken")
    hook = configure(env)
    _, stderr = hook.communicate(timeout=30)
    assert hook.returncode == 1 and "map: 'broken' is incomplete (no image broken.pgm" in stderr
    assert not os.path.lexists(folder / "current_map.yaml")
    (options / "map").write_text("latest")
    hook = configure(env)
    stdout, stderr = hook.communicate(timeout=30)
    assert hook.returncode == 0, stderr
    assert os.readlink(folder / "current_map.yaml") == "good.yaml"
    assert "the current map is now good" in stdout

