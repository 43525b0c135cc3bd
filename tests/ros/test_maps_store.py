"""turtlebot3c_maps.map_store and the maps command line, on a plain folder (no snap, no ROS master)."""
import io
import json
import os
import subprocess

import numpy as np
import pytest
from PIL import Image

from testkit import ros_harness
from turtlebot3c_maps import map_files
from turtlebot3c_maps.map_store import MapStore, MapStoreError, check_name, encode_png, preview_pixels

MAPS_TOOL = ros_harness.PRIME_ROS / "lib" / "turtlebot3c_maps" / "maps"
YAML = ("image: {image}\nresolution: {resolution}\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def grid(width=6, height=4):
    """A map with free, occupied and unknown cells, different in every row (so flips show)."""
    data = np.full((height, width), -1, dtype=np.int8)
    data[:, : width // 2] = 0
    data[np.arange(height), np.arange(height) % width] = 100
    return map_files.OccupancyMap(data, 0.05, (-1.0, -2.0, 0.0))


def saved(folder, name, occupancy=None, bag=False):
    map_files.save_map(occupancy or grid(), os.path.join(folder, name))
    if bag:
        (folder / f"{name}.bag").write_bytes(b"#ROSBAG V2.0\nrest")
    return folder / f"{name}.yaml"


@pytest.fixture
def store(tmp_path):
    folder = tmp_path / "maps"
    folder.mkdir()
    return MapStore(folder)


def folder_of(store):
    return sorted(os.listdir(store.folder))


def test_png_preview_decodes_to_the_map_as_map_saver_draws_it():
    occupancy = grid()
    png = encode_png(preview_pixels(occupancy))
    decoded = np.array(Image.open(io.BytesIO(png)))
    assert decoded.shape == (4, 6) and decoded.dtype == np.uint8
    np.testing.assert_array_equal(decoded, map_files.trinary_pixels(occupancy.data))


def test_png_preview_scales_each_cell_to_a_square_of_pixels():
    decoded = np.array(Image.open(io.BytesIO(encode_png(preview_pixels(grid(), scale=3)))))
    assert decoded.shape == (12, 18)
    np.testing.assert_array_equal(decoded[::3, ::3], map_files.trinary_pixels(grid().data))


def test_list_gives_size_in_cells_and_metres_and_the_current_map(store, tmp_path):
    saved(tmp_path / "maps", "small", grid(6, 4))
    saved(tmp_path / "maps", "large", grid(40, 20), bag=True)
    store.set_current("large")
    infos = {info.name: info for info in store.maps()}
    assert store.names() == ["large", "small"] and store.current_name() == "large"
    assert (infos["large"].width, infos["large"].height, infos["large"].size_metres) == (40, 20, (2.0, 1.0))
    assert infos["large"].has_bag and not infos["small"].has_bag and infos["small"].problem is None


def test_files_in_transit_hidden_files_and_the_link_are_not_maps(store, tmp_path):
    folder = tmp_path / "maps"
    saved(folder, "kept")
    saved(folder, "new_map")
    (folder / ".saving.x").mkdir()
    store.set_current("kept")
    assert store.names() == ["kept"]


def test_an_unreadable_map_is_listed_with_its_problem(store, tmp_path):
    saved(tmp_path / "maps", "broken")
    (tmp_path / "maps" / "broken.pgm").write_bytes(b"P5\n6 4\n255\n")
    [info] = store.maps()
    assert info.name == "broken" and "truncated" in info.problem and info.size_metres is None


def test_rename_moves_image_and_bag_and_the_current_link_follows(store, tmp_path):
    saved(tmp_path / "maps", "2026-01-02_03-04-05", bag=True)
    store.set_current("2026-01-02_03-04-05")
    before = map_files.load_map(store.path("2026-01-02_03-04-05"))
    modified = os.stat(store.path("2026-01-02_03-04-05", ".pgm")).st_mtime
    store.rename("2026-01-02_03-04-05", "kitchen")
    assert folder_of(store) == ["current_map.yaml", "kitchen.bag", "kitchen.pgm", "kitchen.yaml"]
    assert os.readlink(store.path("current_map")) == "kitchen.yaml"
    assert map_files.load_map(store.path("current_map")) == before
    assert os.stat(store.path("kitchen", ".pgm")).st_mtime == modified  # its date stays


def test_rename_never_replaces_another_map(store, tmp_path):
    saved(tmp_path / "maps", "a")
    saved(tmp_path / "maps", "b")
    with pytest.raises(MapStoreError, match="the name b is taken"):
        store.rename("a", "b")
    assert folder_of(store) == ["a.pgm", "a.yaml", "b.pgm", "b.yaml"]


@pytest.mark.parametrize("name", ["", "current_map", "new_map", "latest", ".hidden", "-x", "a/b", "../up", "a b",
                                  "x.yaml", "é", "a" * 101])
def test_names_that_cannot_name_a_map_are_refused(name):
    with pytest.raises(MapStoreError, match="cannot name a map"):
        check_name(name)


def test_remove_refuses_the_current_map_and_removes_another_with_its_bag(store, tmp_path):
    saved(tmp_path / "maps", "current", bag=True)
    saved(tmp_path / "maps", "old", bag=True)
    store.set_current("current")
    with pytest.raises(MapStoreError, match="is the current map"):
        store.remove("current")
    store.remove("old")
    assert folder_of(store) == ["current.bag", "current.pgm", "current.yaml", "current_map.yaml"]


def test_unknown_map_is_named_with_the_known_ones(store, tmp_path):
    saved(tmp_path / "maps", "a")
    with pytest.raises(MapStoreError, match=r"there is no map 'b' .*\(maps: a\)"):
        store.remove("b")


def test_export_then_import_gives_the_same_map_under_its_name(store, tmp_path):
    saved(tmp_path / "maps", "kitchen", bag=True)
    out = tmp_path / "usb"
    out.mkdir()
    store.export("kitchen", out, with_bag=True)
    assert sorted(os.listdir(out)) == ["kitchen.bag", "kitchen.pgm", "kitchen.yaml"]
    other = MapStore(tmp_path / "other")
    assert other.import_map(out) == "kitchen"
    assert map_files.load_map(other.path("kitchen")) == map_files.load_map(store.path("kitchen"))
    assert (tmp_path / "other" / "kitchen.bag").read_bytes() == b"#ROSBAG V2.0\nrest"
    assert other.import_map(out / "kitchen.yaml", name="kitchen-copy") == "kitchen-copy"


def test_export_never_overwrites(store, tmp_path):
    saved(tmp_path / "maps", "kitchen")
    out = tmp_path / "usb"
    out.mkdir()
    (out / "kitchen.pgm").write_bytes(b"mine")
    with pytest.raises(MapStoreError, match="already exist"):
        store.export("kitchen", out)
    assert sorted(os.listdir(out)) == ["kitchen.pgm"] and (out / "kitchen.pgm").read_bytes() == b"mine"


def incoming(tmp_path, image="map.pgm", resolution="0.05", image_bytes=None, name="map"):
    folder = tmp_path / "incoming"
    folder.mkdir(exist_ok=True)
    (folder / f"{name}.yaml").write_text(YAML.format(image=image, resolution=resolution))
    if image_bytes is not None:
        (folder / "map.pgm").write_bytes(image_bytes)
    return folder / f"{name}.yaml"


GOOD_PGM = b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254])


@pytest.mark.parametrize("case, reason", [
    (dict(image_bytes=None), "its image map.pgm .* does not exist"),
    (dict(resolution='"0.05"', image_bytes=GOOD_PGM), "resolution must be a number"),
    (dict(resolution="[0.05]", image_bytes=GOOD_PGM), "resolution must be a number"),
    (dict(image="../../etc/passwd", image_bytes=GOOD_PGM), "not a plain file name"),
    (dict(image="/etc/passwd", image_bytes=GOOD_PGM), "is an absolute path"),
    (dict(image_bytes=b"P6\n1 1\n255\n\x00\x00\x00"), "is not a PGM image"),
    (dict(image_bytes=b"\x89PNG\r\n\x1a\n"), "is not a PGM image"),
    (dict(image_bytes=b"P5\n2 2\n255\n\x00"), "truncated"),
])
def test_bad_import_is_rejected_with_the_reason_and_leaves_nothing(store, tmp_path, case, reason):
    source = incoming(tmp_path, **case)
    with pytest.raises((MapStoreError, map_files.MapFileError), match=reason):
        store.import_map(source)
    assert folder_of(store) == []


def test_import_refuses_an_image_that_is_a_link(store, tmp_path):
    source = incoming(tmp_path)
    os.symlink("/etc/passwd", source.parent / "map.pgm")
    with pytest.raises(MapStoreError, match="not a regular file"):
        store.import_map(source)
    assert folder_of(store) == []


def test_import_refuses_a_bag_that_is_not_a_ros_bag_and_leaves_nothing(store, tmp_path):
    source = incoming(tmp_path, image_bytes=GOOD_PGM)
    (source.parent / "map.bag").write_bytes(b"not a bag")
    with pytest.raises(MapStoreError, match="is not a ROS 1 bag"):
        store.import_map(source)
    assert folder_of(store) == []


def test_import_refuses_a_taken_name_and_keeps_the_map_there(store, tmp_path):
    saved(tmp_path / "maps", "map")
    before = (tmp_path / "maps" / "map.pgm").read_bytes()
    with pytest.raises(MapStoreError, match="the name map is taken"):
        store.import_map(incoming(tmp_path, image_bytes=GOOD_PGM))
    assert folder_of(store) == ["map.pgm", "map.yaml"] and (tmp_path / "maps" / "map.pgm").read_bytes() == before


def test_import_of_a_folder_with_several_maps_asks_for_the_file(store, tmp_path):
    incoming(tmp_path, image_bytes=GOOD_PGM)
    incoming(tmp_path, name="other")
    with pytest.raises(MapStoreError, match="holds 2 map YAML files"):
        store.import_map(tmp_path / "incoming")


def test_an_interrupted_import_leaves_only_a_hidden_staging_folder_that_the_next_change_clears(store, tmp_path):
    saved(tmp_path / "maps", "a")
    (tmp_path / "maps" / ".import.abc").mkdir()
    (tmp_path / "maps" / ".import.abc" / "a.pgm").write_bytes(b"half")
    assert store.names() == ["a"]
    with store.changing():
        pass
    assert not [entry for entry in folder_of(store) if entry.startswith(".import")]


def run_tool(*args, env=None):
    return subprocess.run([str(MAPS_TOOL)] + [str(arg) for arg in args], capture_output=True, text=True,
                          env=dict(os.environ, **(env or {})), timeout=60)


def test_command_line_lists_as_json_and_refuses_changes_without_root(tmp_path):
    (tmp_path / "maps").mkdir()
    saved(tmp_path / "maps", "kitchen")
    done = run_tool("--folder", tmp_path / "maps", "list", "--json")
    listing = json.loads(done.stdout)
    assert [(item["name"], item["width"], item["height"], item["width_m"]) for item in listing["maps"]] == [
        ("kitchen", 6, 4, 0.3)]
    assert listing["map_option"] == "latest" and listing["current"] is None
    unprivileged = subprocess.run(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", str(MAPS_TOOL),
                                   "--folder", tmp_path / "maps", "remove", "kitchen"],
                                  capture_output=True, text=True, timeout=60)
    assert unprivileged.returncode == 1
    assert "remove changes the robot's maps and needs root: sudo turtlebot3c.maps" in unprivileged.stderr
    assert (tmp_path / "maps" / "kitchen.yaml").exists()


def test_command_line_refuses_hostile_requests_in_one_line_and_lists_past_a_hostile_file(tmp_path):
    # Issue #18 items 7 and 8: a preview too large, a YAML nested too deep; a line each, no traceback.
    (tmp_path / "maps").mkdir()
    saved(tmp_path / "maps", "kitchen")
    (tmp_path / "maps" / "deep.yaml").write_text("image: " + "[" * 20000 + "]" * 20000 + "\n")
    listing = run_tool("--folder", tmp_path / "maps", "list")
    assert listing.returncode == 0 and "Traceback" not in listing.stderr
    assert "unreadable: deep: map file" in listing.stdout and "nesting deeper than 8 levels" in listing.stdout
    shown = run_tool("--folder", tmp_path / "maps", "show", "kitchen", "-o", tmp_path / "k.png", "--scale", "100000")
    assert shown.returncode == 1 and len(shown.stderr.splitlines()) == 1
    assert "show refused: --scale 100000 would make a preview of 600000 x 400000 pixels" in shown.stderr
    assert not (tmp_path / "k.png").exists()
