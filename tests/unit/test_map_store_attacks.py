"""The map store under attack (issue #18): what an unprivileged user can plant in a folder they own, or in a
map given to the owner to import, while root runs the maps app. Each attack is refused with a one-line reason
and changes nothing it should not."""
import os
import threading
import tracemalloc

import numpy as np
import pytest

from turtlebot3c_maps import map_files
from turtlebot3c_maps.map_store import MAX_BAG_BYTES, MapStore, MapStoreError, preview_pixels

GOOD_PGM = b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254])
SECRET_PGM = b"P5\n2 2\n255\n" + bytes([1, 2, 3, 4])
YAML = ("image: {image}\nresolution: 0.05\norigin: {origin}\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")


def grid(width=6, height=4):
    data = np.full((height, width), -1, dtype=np.int8)
    data[:, : width // 2] = 0
    return map_files.OccupancyMap(data, 0.05, (-1.0, -2.0, 0.0))


@pytest.fixture
def store(tmp_path):
    (tmp_path / "maps").mkdir()
    return MapStore(tmp_path / "maps")


def saved(store, name, bag=False):
    map_files.save_map(grid(), os.path.join(store.folder, name))
    if bag:
        with open(store.path(name, ".bag"), "wb") as stream:
            stream.write(b"#ROSBAG V2.0\nsession")


def files_in(folder):
    return sorted(entry for entry in os.listdir(folder) if entry != ".lock")


def victim(tmp_path, name="victim", content=b"root only\n"):
    path = tmp_path / name
    path.write_bytes(content)
    path.chmod(0o600)
    return path


def incoming(tmp_path, image_bytes=GOOD_PGM, origin="[-1.0, -2.0, 0.0]", image="map.pgm"):
    folder = tmp_path / "incoming"
    folder.mkdir(exist_ok=True)
    (folder / "map.yaml").write_text(YAML.format(image=image, origin=origin))
    if image_bytes is not None:
        (folder / "map.pgm").write_bytes(image_bytes)
    return folder / "map.yaml"


# --- 1. export writes only new files of its own, never through a link ---------------------------

@pytest.mark.parametrize("planted", ["hall.yaml.part", "hall.pgm.part"])
@pytest.mark.parametrize("target", ["a root-only file", "another map's image"])
def test_export_never_writes_through_a_link_planted_in_the_target_folder(store, tmp_path, planted, target):
    saved(store, "hall")
    saved(store, "other")
    secret = victim(tmp_path) if target == "a root-only file" else store.path("other", ".pgm")
    before = (open(secret, "rb").read(), os.stat(secret).st_mode)
    out = tmp_path / "usb"
    out.mkdir()
    os.symlink(secret, out / planted)
    store.export("hall", out)
    assert (open(secret, "rb").read(), os.stat(secret).st_mode) == before
    assert map_files.load_map(out / "hall.yaml") == map_files.load_map(store.path("hall"))
    assert not (out / "hall.yaml").is_symlink() and not (out / "hall.pgm").is_symlink()
    assert os.readlink(out / planted) == str(secret)  # the user's own link is theirs to keep


def test_export_keeps_the_image_date_and_refuses_a_name_taken_by_a_link(store, tmp_path):
    saved(store, "hall")
    os.utime(store.path("hall", ".pgm"), (1000000000, 1000000000))
    out = tmp_path / "usb"
    out.mkdir()
    store.export("hall", out)
    assert os.stat(out / "hall.pgm").st_mtime == 1000000000
    elsewhere = tmp_path / "usb2"
    elsewhere.mkdir()
    os.symlink(victim(tmp_path), elsewhere / "hall.pgm")
    with pytest.raises(MapStoreError, match="already exist"):
        store.export("hall", elsewhere)
    assert files_in(elsewhere) == ["hall.pgm"]


# --- 2. a map is NAME.yaml + NAME.pgm (+ NAME.bag): nothing its YAML names is touched ----------

def copy_naming(store, name, image):
    with open(store.path(name), "w") as stream:
        stream.write(YAML.format(image=image, origin="[0.0, 0.0, 0.0]"))


def test_removing_a_yaml_that_names_another_maps_image_removes_only_its_own_files(store):
    saved(store, "current", bag=True)
    store.set_current("current")
    copy_naming(store, "copy", "current.pgm")
    store.remove("copy")
    assert files_in(store.folder) == ["current.bag", "current.pgm", "current.yaml", "current_map.yaml"]
    assert map_files.load_map(store.path("current_map")) == map_files.load_map(store.path("current"))


@pytest.mark.parametrize("image", ["current.pgm", "current_map.yaml", "current.yaml", ".lock"])
def test_renaming_a_yaml_that_names_another_file_is_refused_and_moves_nothing(store, image):
    saved(store, "current")
    store.set_current("current")
    copy_naming(store, "copy", image)
    before = files_in(store.folder)
    with pytest.raises(MapStoreError, match=r"map copy: its YAML names the image .*, not copy\.pgm"):
        store.rename("copy", "moved")
    assert files_in(store.folder) == before
    info = {entry.name: entry for entry in store.maps()}
    assert "not copy.pgm" in info["copy"].problem and info["current"].problem is None


# --- 3 is the map folder's rule for "latest": tests/unit/test_map_folder_rule.py ----------------

# --- 4. import reads each file once, through a descriptor, never through a link --------------

@pytest.mark.timeout(120)
def test_import_never_takes_a_file_swapped_for_a_link_while_it_runs(store, tmp_path):
    secret = victim(tmp_path, "secret.pgm", SECRET_PGM)
    source = incoming(tmp_path)
    folder = source.parent
    stop = threading.Event()

    def swap():  # the attacker: map.pgm is a regular file when looked at, a link when read, and so on
        while not stop.is_set():
            os.symlink(secret, folder / "link.tmp")
            os.rename(folder / "link.tmp", folder / "map.pgm")
            (folder / "file.tmp").write_bytes(GOOD_PGM)
            os.rename(folder / "file.tmp", folder / "map.pgm")

    swapper = threading.Thread(target=swap, daemon=True)
    swapper.start()
    imported = []
    try:
        for attempt in range(300):
            try:
                imported.append(store.import_map(source, name=f"m{attempt}"))
            except MapStoreError as refused:
                assert "\n" not in str(refused)
    finally:
        stop.set()
        swapper.join()
    stolen = [name for name in imported if open(store.path(name, ".pgm"), "rb").read() == SECRET_PGM]
    assert imported and not stolen


@pytest.mark.parametrize("target", ["/dev/zero", "fifo"])
def test_import_refuses_an_image_that_is_a_device_or_a_fifo(store, tmp_path, target):
    source = incoming(tmp_path, image_bytes=None)
    if target == "fifo":
        os.mkfifo(source.parent / "map.pgm")
    else:
        os.symlink(target, source.parent / "map.pgm")
    with pytest.raises(MapStoreError, match="not a regular file"):
        store.import_map(source)
    assert files_in(store.folder) == []


# --- 7. limits, checked before reading ----------------------------------------------------------

def test_import_refuses_an_image_over_the_cell_limit_before_reading_its_pixels(store, tmp_path):
    header = b"P5\n2100 2000\n255\n"
    assert 2100 * 2000 > map_files.MAX_MAP_CELLS
    source = incoming(tmp_path, image_bytes=header + bytes(2100 * 2000))
    with pytest.raises(MapStoreError, match="over the limit of 4000000"):
        store.import_map(source)
    assert files_in(store.folder) == []


@pytest.mark.timeout(60)
def test_import_refuses_a_bag_over_the_size_limit_unread(store, tmp_path):
    source = incoming(tmp_path)
    with open(source.parent / "map.bag", "wb") as stream:  # sparse: no disk used
        stream.truncate(MAX_BAG_BYTES + 1)
    with pytest.raises(MapStoreError, match="over the limit"):
        store.import_map(source)
    assert files_in(store.folder) == []


def test_listing_reads_an_image_header_not_its_pixels(store):
    map_files.write_pgm(store.path("large", ".pgm"), np.zeros((2000, 2000), dtype=np.uint8))
    with open(store.path("large"), "w") as stream:
        stream.write(YAML.format(image="large.pgm", origin="[0.0, 0.0, 0.0]"))
    tracemalloc.start()
    try:
        [info] = store.maps()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (info.width, info.height, info.problem) == (2000, 2000, None)
    assert peak < 1000000  # the image is 4 MB


def test_a_preview_over_the_pixel_limit_is_refused_before_it_is_drawn():
    with pytest.raises(MapStoreError, match=r"over the limit of 16000000; this map allows --scale 816 at most"):
        preview_pixels(grid(6, 4), scale=100000)


# --- 8. one bad file is a listed problem, never a traceback for everyone --------------------------

def test_a_hostile_yaml_in_the_folder_is_listed_as_a_problem_and_the_rest_listed(store):
    saved(store, "good")
    with open(store.path("deep"), "w") as stream:
        stream.write("image: " + "[" * 20000 + "]" * 20000 + "\n")
    problems = {info.name: info.problem for info in store.maps()}
    assert problems["good"] is None and "nesting deeper than" in problems["deep"]


# --- 9. a valid map imports whatever its numbers look like; errors name the owner's files -----------

def test_import_of_an_origin_with_an_exponent_keeps_it(store, tmp_path):
    source = incoming(tmp_path, origin="[-10.0, 1.0e-05, 0.0]")
    store.import_map(source)
    assert map_files.load_map(store.path("map")).origin == (-10.0, 1.0e-05, 0.0)


def test_an_import_refusal_names_the_given_files_not_a_staging_copy(store, tmp_path):
    source = incoming(tmp_path, image_bytes=b"P5\n2 2\n255\n\x00")
    with pytest.raises(MapStoreError) as refused:
        store.import_map(source)
    assert str(source.parent / "map.pgm") in str(refused.value) and ".import." not in str(refused.value)
