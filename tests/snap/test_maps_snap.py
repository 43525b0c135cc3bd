"""Maps through the snap (snapsim): the maps app, the `map` option and navigation on the chosen map."""
import io
import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from testkit.ros_harness import wait_until
from testkit.snap_system import (
    SNAPSIM,
    app_shell,
    emptied_map_folder,
    install_turtlebot3c,
    main_command_line,
)
from turtlebot3c_maps import map_files

NOBODY = 65534
GOOD_PGM = b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254])
YAML = ("image: {image}\nresolution: {resolution}\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


@pytest.fixture(scope="module")
def system(ros_master):
    # A folder any user can traverse, so the unprivileged user's test reaches the system.
    folder = Path(tempfile.mkdtemp(prefix="snap-maps-app-"))
    folder.chmod(0o755)
    system = install_turtlebot3c(folder, ros_master)
    yield system
    system.shutdown()
    shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture
def maps(system):
    """The map folder, emptied, with map=latest (maps added by a test are current once the option is set)."""
    folder = emptied_map_folder(system)
    system.snapsim("set", "turtlebot3c", "map=latest")
    return folder


def grid(width, height):
    data = np.full((height, width), -1, dtype=np.int8)
    data[:, : width // 2] = 0
    data[0, :] = 100
    return map_files.OccupancyMap(data, 0.05, (0.0, 0.0, 0.0))


def add_map(maps, name, width=8, height=6, age=0.0, bag=False):
    """A map as mapping leaves it, dated `age` seconds ago."""
    map_files.save_map(grid(width, height), maps / name)
    when = time.time() - age
    os.utime(maps / f"{name}.pgm", (when, when))
    if bag:
        (maps / f"{name}.bag").write_bytes(b"#ROSBAG V2.0\nsession")


def app(system, *args, uid=None):
    """`turtlebot3c.maps ARGS` as root, or as the user `uid`."""
    command = [str(arg) for arg in args]
    if uid is None:
        return system.snapsim("run", "turtlebot3c.maps", *command, check=False)
    prefix = ["setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups"]
    env = dict(system.env, HOME="/nonexistent")
    return subprocess.run(prefix + [str(SNAPSIM), "--root", str(system.root), "run", "turtlebot3c.maps"] + command,
                          env=env, capture_output=True, text=True, timeout=120)


def stdout_of(done):
    """The app's own output: without the host's ROS_DISTRO notice that sourcing Debian's ROS prints in snapsim."""
    return "".join(line for line in done.stdout.splitlines(keepends=True) if "ROS_DISTRO was set to" not in line)


def current(maps):
    return os.readlink(maps / "current_map.yaml")


def listing(system):
    done = app(system, "list", "--json")
    assert done.returncode == 0, done.stderr
    return json.loads(stdout_of(done))


def navigation_status(system):
    return system.status("turtlebot3c", "navigation")


# --- the maps app --------------------------------------------------------------------------

def test_list_shows_every_map_with_its_date_size_and_which_is_current(system, maps):
    add_map(maps, "2026-01-02_03-04-05", 8, 6, age=100, bag=True)
    add_map(maps, "kitchen", 40, 20, age=10)
    system.snapsim("set", "turtlebot3c", "map=2026-01-02_03-04-05")
    done = app(system, "list")
    assert done.returncode == 0, done.stderr
    lines = stdout_of(done).splitlines()
    assert lines[0].split() == ["Name", "Date", "Cells", "Size", "(m)", "Resolution", "Bag", "Current"]
    assert lines[1].split()[0] == "2026-01-02_03-04-05" and lines[1].split()[3:] == [
        "8x6", "0.40", "x", "0.30", "0.05", "m", "yes", "*"]
    assert lines[2].split()[3:] == ["40x20", "2.00", "x", "1.00", "0.05", "m", "-"]
    assert "map=2026-01-02_03-04-05: navigation uses this map" in done.stdout
    document = listing(system)
    assert document["folder"] == str(maps) and document["current"] == "2026-01-02_03-04-05"
    assert [(item["name"], item["width_m"], item["height_m"], item["current"]) for item in document["maps"]] == [
        ("2026-01-02_03-04-05", 0.4, 0.3, True), ("kitchen", 2.0, 1.0, False)]


def test_show_writes_a_png_preview_and_prints_its_path(system, maps):
    add_map(maps, "kitchen", 12, 7)
    done = app(system, "show", "kitchen")
    assert done.returncode == 0, done.stderr
    path = Path(done.stdout.strip().splitlines()[-1])
    assert path == system.root / "root/snap/turtlebot3c/common/previews/kitchen.png"
    picture = np.array(Image.open(io.BytesIO(path.read_bytes())))
    np.testing.assert_array_equal(picture, map_files.read_pnm(maps / "kitchen.pgm")[:, :, 0])


def test_reading_works_for_an_unprivileged_user_and_changes_say_they_need_root(system, maps):
    add_map(maps, "kitchen")
    home = system.root / "nonexistent"
    runtime = system.root / "run" / "user" / str(NOBODY)
    for folder in (home, runtime):
        folder.mkdir(parents=True, exist_ok=True)
        os.chown(folder, NOBODY, NOBODY)
    done = app(system, "list", uid=NOBODY)
    assert done.returncode == 0, done.stderr
    assert stdout_of(done).splitlines()[1].split()[0] == "kitchen"
    shown = app(system, "show", "kitchen", uid=NOBODY)
    assert shown.returncode == 0, shown.stderr
    assert Path(stdout_of(shown).strip()).read_bytes().startswith(b"\x89PNG")
    for change in (["rename", "kitchen", "lab"], ["remove", "kitchen"], ["import", maps]):
        refused = app(system, *change, uid=NOBODY)
        assert refused.returncode == 1
        assert f"{change[0]} changes the robot's maps and needs root: sudo turtlebot3c.maps" in refused.stderr
    assert sorted(path.name for path in maps.iterdir() if path.name != ".lock") == ["kitchen.pgm", "kitchen.yaml"]


def test_rename_of_the_chosen_map_keeps_it_chosen_under_its_new_name(system, maps):
    add_map(maps, "2026-01-02_03-04-05", bag=True)
    add_map(maps, "newer")
    system.snapsim("set", "turtlebot3c", "map=2026-01-02_03-04-05")
    done = app(system, "rename", "2026-01-02_03-04-05", "kitchen")
    assert done.returncode == 0, done.stderr
    assert current(maps) == "kitchen.yaml" and system.config("turtlebot3c")["map"] == "kitchen"
    assert sorted(path.name for path in maps.glob("kitchen*")) == ["kitchen.bag", "kitchen.pgm", "kitchen.yaml"]
    assert not list(maps.glob("2026-*"))


def test_remove_refuses_the_current_map_and_removes_another_with_its_bag(system, maps):
    add_map(maps, "old", age=100, bag=True)
    add_map(maps, "new")
    system.snapsim("set", "turtlebot3c", "map=latest")
    refused = app(system, "remove", "new")
    assert refused.returncode == 1 and "new is the current map and stays" in refused.stderr
    done = app(system, "remove", "old")
    assert done.returncode == 0, done.stderr
    assert sorted(path.name for path in maps.iterdir() if not path.name.startswith(".")) == [
        "current_map.yaml", "new.pgm", "new.yaml"]


def test_export_and_import_move_a_map_between_robots_and_latest_makes_it_current(system, maps, tmp_path):
    add_map(maps, "kitchen", 9, 5, bag=True)
    usb = tmp_path / "usb"
    usb.mkdir()
    exported = app(system, "export", "kitchen", usb, "--with-bag")
    assert exported.returncode == 0, exported.stderr
    assert sorted(path.name for path in usb.iterdir()) == ["kitchen.bag", "kitchen.pgm", "kitchen.yaml"]
    imported = app(system, "import", usb / "kitchen.yaml", "--name", "kitchen-2")
    assert imported.returncode == 0, imported.stderr
    assert current(maps) == "kitchen-2.yaml" and "kitchen-2 is now the current map (map=latest)" in imported.stdout
    assert map_files.load_map(maps / "kitchen-2.yaml") == map_files.load_map(maps / "kitchen.yaml")
    assert (maps / "kitchen-2.bag").read_bytes() == (maps / "kitchen.bag").read_bytes()


def test_an_import_while_a_map_is_chosen_is_listed_but_not_current(system, maps, tmp_path):
    add_map(maps, "chosen")
    system.snapsim("set", "turtlebot3c", "map=chosen")
    source = tmp_path / "incoming"
    source.mkdir()
    add_map(source, "other")
    done = app(system, "import", source)
    assert done.returncode == 0, done.stderr
    assert current(maps) == "chosen.yaml" and "the current map stays chosen" in done.stdout
    assert [item["name"] for item in listing(system)["maps"]] == ["chosen", "other"]


@pytest.mark.parametrize("image, resolution, image_bytes, reason", [
    ("map.pgm", "0.05", None, "does not exist"),
    ("map.pgm", "'0.05'", GOOD_PGM, "resolution must be a number"),
    ("../../etc/passwd", "0.05", GOOD_PGM, "not a plain file name"),
    ("/etc/passwd", "0.05", GOOD_PGM, "is an absolute path"),
    ("map.pgm", "0.05", b"P6\n1 1\n255\n\x00\x00\x00", "is not a PGM image"),
])
def test_a_bad_import_is_rejected_with_the_reason_and_nothing_is_left_behind(
        system, maps, tmp_path, image, resolution, image_bytes, reason):
    add_map(maps, "kept")
    system.snapsim("set", "turtlebot3c", "map=latest")
    before = sorted(path.name for path in maps.iterdir() if path.name != ".lock")
    source = tmp_path / "bad"
    source.mkdir()
    (source / "map.yaml").write_text(YAML.format(image=image, resolution=resolution))
    if image_bytes is not None:
        (source / "map.pgm").write_bytes(image_bytes)
    done = app(system, "import", source)
    assert done.returncode == 1 and "maps: import refused:" in done.stderr and reason in done.stderr, done.stderr
    assert sorted(path.name for path in maps.iterdir() if path.name != ".lock") == before
    assert current(maps) == "kept.yaml"


# --- the map option ------------------------------------------------------------------------

def test_an_unknown_map_is_rejected_listing_the_known_ones_and_nothing_changes(system, maps):
    add_map(maps, "hall", age=50)
    add_map(maps, "kitchen")
    system.snapsim("set", "turtlebot3c", "map=hall")
    before = system.config("turtlebot3c")
    done = system.snapsim("set", "turtlebot3c", "map=garage", check=False)
    assert done.returncode == 1
    assert "map: there is no map 'garage'; known maps: hall, kitchen; or latest" in done.stderr
    assert system.config("turtlebot3c") == before and current(maps) == "hall.yaml"


@pytest.mark.parametrize("value", ["../kitchen", "current_map", "new_map", ".hidden", "-kitchen", "kit chen",
                                   "$(touch {marker})", "`touch {marker}`"])
def test_a_map_value_that_is_no_map_name_is_rejected_and_runs_nothing(system, maps, tmp_path, value):
    marker = tmp_path / "pwned"
    add_map(maps, "kitchen")
    done = system.snapsim("set", "turtlebot3c", f"map={value.format(marker=marker)}", check=False)
    assert done.returncode == 1 and "map: '" in done.stderr and "is not allowed" in done.stderr
    assert not marker.exists() and system.config("turtlebot3c")["map"] == "latest"


def test_choosing_a_map_while_navigation_is_stopped_switches_it_and_starts_nothing(system, maps):
    add_map(maps, "hall", age=50)
    add_map(maps, "kitchen")
    system.snapsim("set", "turtlebot3c", "map=latest")
    assert current(maps) == "kitchen.yaml"
    before = navigation_status(system)
    system.snapsim("set", "turtlebot3c", "map=hall")
    assert current(maps) == "hall.yaml"
    assert navigation_status(system) == before and before["state"] == "inactive"


def test_latest_follows_the_newest_map_again(system, maps):
    add_map(maps, "a-newest", age=1)
    add_map(maps, "b-older", age=100)
    system.snapsim("set", "turtlebot3c", "map=b-older")
    assert current(maps) == "b-older.yaml"
    system.snapsim("set", "turtlebot3c", "map=latest")
    assert current(maps) == "a-newest.yaml"


def install_saved_map(system, maps, ros_master):
    """What stopping mapping does after save_map.sh: install_last_map.sh, through the mapping app's chain."""
    map_files.save_map(grid(5, 5), maps / "new_map")
    return app_shell(system, "mapping", "install_last_map.sh", ros_master.uri)


def test_a_new_map_becomes_current_with_latest_and_is_only_listed_when_a_map_is_chosen(system, maps, ros_master):
    add_map(maps, "hall", age=50)
    system.snapsim("set", "turtlebot3c", "map=hall")
    done = install_saved_map(system, maps, ros_master)
    [new] = [name for name in (item["name"] for item in listing(system)["maps"]) if name != "hall"]
    assert current(maps) == "hall.yaml"
    assert f"the new map is saved as {maps}/{new}.yaml; the current map stays 'hall'" in done.stdout
    assert f"sudo snap set turtlebot3c map={new}" in done.stdout
    system.snapsim("set", "turtlebot3c", "map=latest")
    assert current(maps) == f"{new}.yaml"
    install_saved_map(system, maps, ros_master)
    assert current(maps) not in (f"{new}.yaml", "hall.yaml") and len(listing(system)["maps"]) == 3


def test_choosing_a_map_while_navigation_runs_restarts_it_on_the_new_map(system, maps, ros_master):
    add_map(maps, "hall", 30, 10, age=50)
    add_map(maps, "kitchen", 16, 12)
    system.snapsim("set", "turtlebot3c", "map=latest")
    ros_master.probe.subscribe("/map", "nav_msgs/OccupancyGrid")
    system.snapsim("start", "turtlebot3c.navigation")
    try:
        assert f"map_file:={maps}/current_map.yaml" in main_command_line(system, "navigation")
        ros_master.probe.wait_for_message("/map", "nav_msgs/OccupancyGrid", timeout=60,
                                          where=lambda grid: grid["info"]["width"] == 16)
        before = navigation_status(system)
        mark = ros_master.probe.count("/map")
        system.snapsim("set", "turtlebot3c", "map=hall")
        wait_until(lambda: navigation_status(system)["supervisor"] not in (None, before["supervisor"]), 60,
                   lambda: f"navigation was not restarted: {navigation_status(system)}")
        assert navigation_status(system)["main_pid"] != before["main_pid"]
        assert "navigation: no map" not in system.logs("turtlebot3c.navigation")
        message = ros_master.probe.wait_for_message("/map", "nav_msgs/OccupancyGrid", timeout=60, start=mark,
                                                    where=lambda grid: grid["info"]["width"] == 30)
        assert message["info"]["height"] == 10
    finally:
        system.snapsim("stop", "turtlebot3c.navigation")
