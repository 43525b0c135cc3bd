"""Refreshing from a revision that kept maps in root's $SNAP_USER_COMMON/map: every map moves to $SNAP_COMMON/maps.

The earlier revision is the snap as this repository had it before the maps moved, saving
maps with its own scripts: OLD_REVISION, its snap/ folder as commit 927994b left it
(`git archive 927994b snap`), kept whole with the tests so that they need no git history.
"""
import hashlib
import os
import shutil
import subprocess

import numpy as np
import pytest

from testkit import ros_harness
from testkit.snap_system import (
    MAP_FOLDER,
    REPO,
    SnapSystem,
    app_shell,
    main_command_line,
)
from turtlebot3c_maps import map_files

OLD_REVISION = REPO / "tests" / "fixtures" / "snap-before-maps-moved"  # the last with maps in $SNAP_USER_COMMON/map
OLD_FOLDER = "root/snap/turtlebot3c/common/map"
MIGRATE = REPO / "snap" / "local" / "migrate_maps.sh"
MAP = {"header": {"frame_id": "map"},
       "info": {"resolution": 0.05, "width": 4, "height": 3, "origin": {"position": {"x": -1.0, "y": -2.0}}},
       "data": [0, 0, 100, -1] * 3}


@pytest.fixture
def system(make_master, tmp_path):
    master = make_master()
    system = SnapSystem(tmp_path / "root", build_dir=ros_harness.BUILD,
                        etc_environment={"ROS_MASTER_URI": master.uri, "ROS_HOSTNAME": "127.0.0.1"})
    system.master = master
    system.snapsim("install", OLD_REVISION, "--dangerous")
    system.wait_state("turtlebot3c", "teleop", ["active"])
    master.wait_for_service("/mux/select", timeout=60)
    yield system
    system.shutdown()


def save_with_old_revision(system, old, side, bag):
    """What stopping mapping did in the old revision: a new map (and bag) installed by its install_last_map.sh."""
    old.mkdir(parents=True, exist_ok=True)
    data = np.full((side, side), -1, dtype=np.int8)
    data[: side // 2] = 0
    map_files.save_map(map_files.OccupancyMap(data, 0.05), old / "new_map")
    if bag:
        (old / "new_map.bag").write_bytes(b"#ROSBAG V2.0\n" + bytes(side))
    app_shell(system, "mapping", "install_last_map.sh", system.master.uri)
    return os.readlink(old / "current_map.yaml")[:-len(".yaml")]


def contents(folder):
    """The maps' images and bags (not the YAMLs, which name their images, nor hidden files such as the lock)."""
    return {path.name: hashlib.sha256(path.read_bytes()).hexdigest()
            for path in folder.iterdir() if path.is_file() and not path.is_symlink() and path.suffix != ".yaml"
            and not path.name.startswith(".")}


def test_refresh_moves_every_map_its_image_and_bag_and_keeps_the_chosen_map_current(system):
    old = system.root / OLD_FOLDER
    names = [save_with_old_revision(system, old, side, bag) for side, bag in ((4, True), (6, False), (8, True))]
    assert len(set(names)) == 3
    maps_before = {name: map_files.load_map(old / f"{name}.yaml") for name in names}
    images_and_bags = contents(old)
    assert len(images_and_bags) == 5
    # The old README's way to choose an older map: point the link at it.
    os.symlink(f"{names[0]}.yaml", old / ".current_map.yaml.tmp")
    os.replace(old / ".current_map.yaml.tmp", old / "current_map.yaml")
    (old / ".saving.abc123").mkdir()  # left by a save killed midway
    (old / ".saving.abc123" / "map.pgm").write_bytes(b"P5\n")

    system.snapsim("install", REPO, "--dangerous")  # the refresh

    maps = system.root / MAP_FOLDER
    assert old.is_symlink() and old.resolve() == maps.resolve()  # a reverted revision still finds them
    assert contents(maps) == images_and_bags
    assert {name: map_files.load_map(maps / f"{name}.yaml") for name in names} == maps_before
    for name in names:
        assert (maps / f"{name}.yaml").read_text().splitlines()[0] == f"image: {name}.pgm"
    assert os.readlink(maps / "current_map.yaml") == f"{names[0]}.yaml"
    assert system.config("turtlebot3c")["map"] == names[0]  # chosen by hand, kept chosen
    listed = system.snapsim("run", "turtlebot3c.maps", "list").stdout
    assert f"map={names[0]}: navigation uses this map" in listed
    assert "migrate_maps: the maps moved from" in (
        system.root / "var/lib/snapsim/hook-logs/turtlebot3c.post-refresh.log").read_text()


def test_refresh_while_mapping_runs_keeps_the_session_map_and_moves_it(system):
    system.master.probe.publish("/map", "nav_msgs/OccupancyGrid", MAP, latch=True)
    system.snapsim("start", "turtlebot3c.mapping")
    main_command_line(system, "mapping")

    system.snapsim("install", REPO, "--dangerous")  # stops mapping (the old revision saves), then migrates

    maps = system.root / MAP_FOLDER
    assert (system.root / OLD_FOLDER).resolve() == maps.resolve()
    [saved] = [path.name for path in maps.glob("*.yaml") if path.name != "current_map.yaml"]
    assert os.readlink(maps / "current_map.yaml") == saved and system.config("turtlebot3c")["map"] == "latest"
    assert map_files.load_map(maps / saved).data.shape == (3, 4)
    # mapping was running, so it runs again after the refresh, now saving into the new place
    main_command_line(system, "mapping")
    system.snapsim("stop", "turtlebot3c.mapping")
    assert len([path for path in maps.glob("*.yaml") if path.name != "current_map.yaml"]) == 2
    assert os.readlink(maps / "current_map.yaml") != saved


def test_a_refresh_undone_after_the_move_leaves_the_earlier_revision_every_map(system, tmp_path):
    old = system.root / OLD_FOLDER
    names = [save_with_old_revision(system, old, side, bag=True) for side in (4, 6)]
    failing = tmp_path / "failing-revision"
    shutil.copytree(REPO / "snap", failing / "snap")
    with open(failing / "snap" / "hooks" / "post-refresh", "a") as hook:
        hook.write('echo "post-refresh: failing on purpose" >&2\nexit 1\n')

    done = system.snapsim("install", failing, "--dangerous", check=False)

    assert done.returncode == 1 and "failing on purpose" in done.stderr
    assert os.readlink(system.root / "snap" / "turtlebot3c" / "current") == "x1"  # snapd undid the refresh
    system.wait_state("turtlebot3c", "teleop", ["active"])
    # the earlier revision reads root's old folder, now a link to the new one: every map is there
    assert os.readlink(old / "current_map.yaml") == f"{names[1]}.yaml"
    assert sorted(path.name for path in old.iterdir() if path.suffix in (".yaml", ".pgm", ".bag")) == sorted(
        [f"{name}{suffix}" for name in names for suffix in (".yaml", ".pgm", ".bag")] + ["current_map.yaml"])
    listed = app_shell(system, "mapping", 'ls "$SNAP_USER_COMMON/map/"', system.master.uri).stdout
    assert f"{names[0]}.yaml" in listed and f"{names[1]}.pgm" in listed


# --- migrate_maps.sh itself: interrupted anywhere, run again, nothing lost --------------------

def old_folder_with_maps(folder):
    old = folder / "old"
    old.mkdir(parents=True)
    for number, side in enumerate((3, 5, 7)):
        name = f"2026-01-0{number + 1}_10-00-00"
        map_files.save_map(map_files.OccupancyMap(np.zeros((side, side)), 0.05), old / name)
        (old / f"{name}.bag").write_bytes(b"#ROSBAG V2.0\n" + bytes(side))
    (old / "2026-01-04_10-00-00.bag.active").write_bytes(b"#ROSBAG V2.0\n")  # a session with no map
    os.symlink("2026-01-02_10-00-00.yaml", old / "current_map.yaml")
    return old


def snapshot(folder):
    return {path.name: (os.readlink(path) if path.is_symlink() else path.read_bytes())
            for path in folder.iterdir() if not path.name.startswith(".")} if folder.exists() else {}


def shims(folder, kill_at, links_fail):
    """PATH shims for the commands that change files: the kill_at-th call kills the migration (power cut)."""
    bin_dir = folder / "shims"
    bin_dir.mkdir(exist_ok=True)
    counter = folder / "calls"
    counter.write_text("0")
    for command in ("ln", "mv", "cp", "rm", "sync", "touch", "mkdir", "rmdir"):
        real = shutil.which(command)
        # Hard links (`ln -- SOURCE TARGET`) fail as across file systems; symbolic links still work.
        fail = f'if [ "$1" = "--" ]; then exit 1; fi; exec {real} "$@"' if command == "ln" and links_fail \
            else f'exec {real} "$@"'
        (bin_dir / command).write_text(
            f'#!/bin/bash\ncalls=$(( $(cat {counter}) + 1 )); echo "$calls" >{counter}\n'
            f'if [ "$calls" -eq {kill_at} ]; then kill -KILL "$PPID"; exit 1; fi\n{fail}\n')
        (bin_dir / command).chmod(0o755)
    return bin_dir


def migrate(old, new, path=None):
    env = dict(os.environ, PATH=f"{path}:{os.environ['PATH']}" if path else os.environ["PATH"])
    return subprocess.run(["bash", str(MIGRATE), str(old), str(new)], env=env, capture_output=True, text=True,
                          timeout=60)


@pytest.mark.parametrize("links_fail", [False, True], ids=["same-file-system", "copies"])
def test_a_migration_cut_at_any_step_loses_nothing_and_the_next_run_finishes_it(tmp_path, links_fail):
    reference = snapshot(old_folder_with_maps(tmp_path / "reference"))
    kill_at = 1
    while kill_at < 200:
        case = tmp_path / f"cut-{kill_at}"
        case.mkdir()
        old = old_folder_with_maps(case)
        cut = migrate(old, case / "new", shims(case, kill_at, links_fail))
        merged = dict(snapshot(case / "new"), **snapshot(old))
        for name, content in reference.items():  # every file is somewhere, whole
            assert merged.get(name) == content, (kill_at, name)
        for yaml in (case / "new").glob("*.yaml"):  # a map in the new place always has its image
            if yaml.name != "current_map.yaml":
                assert (case / "new" / f"{yaml.stem}.pgm").exists(), (kill_at, yaml.name)
        finished = migrate(old, case / "new")
        assert finished.returncode == 0, finished.stderr
        assert old.is_symlink() and old.resolve() == (case / "new").resolve(), kill_at
        assert snapshot(case / "new") == reference and not (case / "old.moved").exists(), kill_at
        if cut.returncode == 0:
            break  # this run was never cut: every step has been cut once
        kill_at += 1
    assert 10 < kill_at < 200


def test_a_name_taken_by_another_file_keeps_that_map_in_the_old_place_and_moves_the_rest(tmp_path):
    old = old_folder_with_maps(tmp_path)
    new = tmp_path / "new"
    new.mkdir()
    (new / "2026-01-01_10-00-00.pgm").write_bytes(b"someone else's")
    done = migrate(old, new)
    assert done.returncode == 0, done.stderr
    assert "2026-01-01_10-00-00 stays in" in done.stderr
    assert (new / "2026-01-01_10-00-00.pgm").read_bytes() == b"someone else's"
    assert sorted(path.name for path in old.iterdir()) == [
        "2026-01-01_10-00-00.bag", "2026-01-01_10-00-00.pgm", "2026-01-01_10-00-00.yaml"]
    assert os.readlink(new / "current_map.yaml") == "2026-01-02_10-00-00.yaml"
    assert (new / "2026-01-03_10-00-00.yaml").exists() and (new / "2026-01-04_10-00-00.bag.active").exists()
