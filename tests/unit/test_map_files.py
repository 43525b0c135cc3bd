"""Maps on disk in map_server's PGM + YAML format: save, reload, and every loader mode."""
import os
import re

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from turtlebot3c_maps import map_files
from turtlebot3c_maps.map_files import MapFileError, OccupancyMap, load_map, read_pnm, save_map, trinary_pixels


def sample_map():
    data = np.full((4, 5), -1, dtype=np.int8)
    data[0, :] = 0          # bottom row free
    data[1, 1] = 100        # occupied
    data[1, 2] = 30         # between the thresholds: saved as unknown
    data[2, 3] = 25         # at the free threshold: free
    data[3, 4] = 65         # at the occupied threshold: occupied
    return OccupancyMap(data, 0.05, (-1.25, 2.5, 0.3))


def write_yaml(path, **keys):
    document = {"image": "map.pgm", "resolution": 0.1, "origin": [0.0, 0.0, 0.0], "negate": 0,
                "occupied_thresh": 0.65, "free_thresh": 0.196}
    document.update(keys)
    document = {key: value for key, value in document.items() if value is not None}
    path.write_text(yaml.safe_dump(document))
    return path


def write_p5(path, pixels, maxval=255):
    pixels = np.asarray(pixels, dtype=np.uint8)
    path.write_bytes(f"P5\n{pixels.shape[1]} {pixels.shape[0]}\n{maxval}\n".encode() + pixels.tobytes())


def test_saved_map_reloads_to_the_same_trinary_grid_with_unknown_kept_unknown(tmp_path):
    original = sample_map()
    yaml_path, pgm_path = save_map(original, tmp_path / "new_map")
    loaded = load_map(yaml_path)
    expected = np.where(original.data > 25, np.where(original.data >= 65, 100, -1), original.data)
    expected = np.where(original.data == 25, 0, expected)
    assert loaded.resolution == original.resolution
    assert loaded.origin == original.origin
    assert np.array_equal(loaded.data, expected)
    assert (loaded.data == -1).sum() == (original.data == -1).sum() + 1  # 30 became unknown


def test_round_trip_of_a_trinary_grid_is_exact(tmp_path):
    rng = np.random.RandomState(3)
    data = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(37, 23))
    original = OccupancyMap(data, 0.025, (-3.1, -4.7, -1.2))
    assert load_map(save_map(original, tmp_path / "m")[0]) == original


def test_saved_files_follow_map_saver_layout(tmp_path):
    yaml_path, pgm_path = save_map(sample_map(), tmp_path / "new_map")
    content = open(pgm_path, "rb").read()
    assert content.startswith(b"P5\n")
    pixels = read_pnm(pgm_path)[:, :, 0]
    assert pixels.shape == (4, 5)
    assert list(pixels[-1]) == [254] * 5          # bottom image row = lowest y = free row
    assert pixels[2, 1] == 0 and pixels[2, 2] == 205
    description = yaml.safe_load(open(yaml_path))
    assert description == {"image": "new_map.pgm", "resolution": 0.05, "origin": [-1.25, 2.5, 0.3],
                           "negate": 0, "occupied_thresh": 0.65, "free_thresh": 0.196}


def test_map_saver_pixel_rule_with_custom_thresholds():
    data = np.array([[-1, 0, 10, 11, 49, 50, 100]])
    assert list(trinary_pixels(data, occupied_threshold=50, free_threshold=10)[0]) == \
        [205, 254, 254, 205, 205, 0, 0]


@pytest.mark.parametrize("occupied, free", [(0, 0), (101, 25), (65, 65), (65, -1)])
def test_thresholds_outside_map_saver_limits_are_rejected(tmp_path, occupied, free):
    with pytest.raises(ValueError, match="threshold"):
        save_map(sample_map(), tmp_path / "m", occupied_threshold=occupied, free_threshold=free)
    assert list(tmp_path.iterdir()) == []


def test_saving_into_a_missing_folder_fails_clearly(tmp_path):
    with pytest.raises(MapFileError, match="does not exist"):
        save_map(sample_map(), tmp_path / "absent" / "m")


def test_saving_over_an_existing_map_replaces_it_without_leftovers(tmp_path):
    save_map(sample_map(), tmp_path / "m")
    other = OccupancyMap(np.zeros((2, 2), dtype=np.int8), 0.1)
    save_map(other, tmp_path / "m")
    assert load_map(tmp_path / "m.yaml") == other
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def test_image_path_is_resolved_relative_to_the_yaml_folder(tmp_path, monkeypatch):
    save_map(sample_map(), tmp_path / "m")
    monkeypatch.chdir("/")
    assert load_map(str(tmp_path / "m.yaml")).width == 5


def test_absolute_image_path_is_used_as_is(tmp_path):
    (tmp_path / "images").mkdir()
    write_p5(tmp_path / "images" / "a.pgm", [[0, 254]])
    write_yaml(tmp_path / "a.yaml", image=str(tmp_path / "images" / "a.pgm"))
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[100, 0]]


def test_trinary_mode_thresholds_and_negate(tmp_path):
    write_p5(tmp_path / "map.pgm", [[0, 100, 200, 254, 255]])
    write_yaml(tmp_path / "a.yaml", occupied_thresh=0.6, free_thresh=0.2)
    # occupancy (255 - v) / 255: 1.0, 0.61, 0.216, 0.004, 0.0
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[100, 100, -1, 0, 0]]
    write_yaml(tmp_path / "b.yaml", occupied_thresh=0.6, free_thresh=0.2, negate=1)
    # negated occupancy v / 255: 0.0, 0.39, 0.78, 0.996, 1.0
    assert load_map(tmp_path / "b.yaml").data.tolist() == [[0, -1, 100, 100, 100]]


def test_scale_mode_interpolates_between_the_thresholds(tmp_path):
    write_p5(tmp_path / "map.pgm", [[0, 127, 204, 255]])
    write_yaml(tmp_path / "a.yaml", mode="scale", occupied_thresh=0.65, free_thresh=0.196)
    occupancy = (255 - 127) / 255.0
    middle = int(1 + 98 * (occupancy - 0.196) / (0.65 - 0.196))
    occupancy_204 = (255 - 204) / 255.0
    low = int(1 + 98 * (occupancy_204 - 0.196) / (0.65 - 0.196))
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[100, middle, low, 0]]


def test_raw_mode_copies_pixel_values(tmp_path):
    write_p5(tmp_path / "map.pgm", [[0, 50, 100, 255]])
    write_yaml(tmp_path / "a.yaml", mode="raw")
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[0, 50, 100, -1]]


def test_top_image_row_is_the_highest_y_row(tmp_path):
    write_p5(tmp_path / "map.pgm", [[0, 0], [254, 254], [205, 205]])
    write_yaml(tmp_path / "a.yaml")
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[-1, -1], [0, 0], [100, 100]]


def test_ascii_pgm_with_comments_and_small_maxval_is_scaled_like_sdl_image(tmp_path):
    (tmp_path / "map.pgm").write_text("P2\n# made by hand\n3 1\n# maxval next\n15\n0 15\n# mid\n3\n")
    assert read_pnm(tmp_path / "map.pgm")[:, :, 0].tolist() == [[0, 255, 51]]
    write_yaml(tmp_path / "a.yaml")
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[100, 0, 100]]


def test_colour_image_averages_channels(tmp_path):
    pixels = np.array([[[255, 255, 255], [0, 0, 0], [240, 230, 250]]], dtype=np.uint8)
    (tmp_path / "map.pgm").write_bytes(b"P6\n3 1\n255\n" + pixels.tobytes())
    write_yaml(tmp_path / "a.yaml")
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[0, 100, 0]]


def test_missing_mode_is_trinary_and_unknown_mode_is_rejected(tmp_path):
    write_p5(tmp_path / "map.pgm", [[205]])
    write_yaml(tmp_path / "a.yaml", mode=None)
    assert load_map(tmp_path / "a.yaml").data.tolist() == [[-1]]
    write_yaml(tmp_path / "b.yaml", mode="fancy")
    with pytest.raises(MapFileError, match="mode 'fancy' is not one of trinary, scale, raw"):
        load_map(tmp_path / "b.yaml")


@pytest.mark.parametrize("key", ["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"])
def test_each_required_key_missing_is_named(tmp_path, key):
    write_p5(tmp_path / "map.pgm", [[0]])
    write_yaml(tmp_path / "a.yaml", **{key: None})
    with pytest.raises(MapFileError, match=f"lacks the key\\(s\\) {key}"):
        load_map(tmp_path / "a.yaml")


@pytest.mark.parametrize("keys, message", [
    ({"resolution": "fine"}, "resolution must be a number"),
    ({"resolution": 0}, "resolution must be positive"),
    ({"origin": [1, 2]}, "origin must be"),
    ({"negate": "no"}, "negate must be an integer"),
    ({"image": ""}, "image must be a non-empty"),
])
def test_invalid_values_are_named(tmp_path, keys, message):
    write_p5(tmp_path / "map.pgm", [[0]])
    write_yaml(tmp_path / "a.yaml", **keys)
    with pytest.raises(MapFileError, match=message):
        load_map(tmp_path / "a.yaml")


def test_missing_yaml_missing_image_and_non_mapping_fail_clearly(tmp_path):
    with pytest.raises(MapFileError, match="cannot read map file .*absent.yaml"):
        load_map(tmp_path / "absent.yaml")
    write_yaml(tmp_path / "a.yaml", image="nothing.pgm")
    with pytest.raises(MapFileError, match="cannot read map image .*nothing.pgm"):
        load_map(tmp_path / "a.yaml")
    (tmp_path / "b.yaml").write_text("- just\n- a list\n")
    with pytest.raises(MapFileError, match="not a YAML mapping"):
        load_map(tmp_path / "b.yaml")
    (tmp_path / "c.yaml").write_text("image: [unclosed\n")
    with pytest.raises(MapFileError, match="not valid YAML"):
        load_map(tmp_path / "c.yaml")


@pytest.mark.parametrize("content, message", [
    (b"\x89PNG\r\n", "not a PGM/PPM"),
    (b"P5\n4 4\n255\n\x00\x00", "truncated"),
    (b"P5\n4\n", "malformed header"),
    (b"P5\n1 1\n65535\n\x00\x00", "maxval 65535 unsupported"),
    (b"P2\n2 1\n10\n3 11\n", "above its maxval"),
    (b"P2\n2 1\n255\n3 x\n", "non-numeric"),
])
def test_bad_images_fail_clearly(tmp_path, content, message):
    (tmp_path / "map.pgm").write_bytes(content)
    write_yaml(tmp_path / "a.yaml")
    with pytest.raises(MapFileError, match=message):
        load_map(tmp_path / "a.yaml")


def test_message_fields_round_trip():
    original = sample_map()
    rebuilt = OccupancyMap.from_message(original.grid_message_data(), original.width, original.height,
                                        original.resolution, original.origin)
    assert rebuilt == original
    with pytest.raises(ValueError, match="expected 5 x 4"):
        OccupancyMap.from_message([0] * 3, 5, 4, 0.05, (0, 0, 0))


# --- hostile files (issue #18): refused in one line, quickly, whatever they hold --------------

def alias_bomb(levels=8, width=6):
    """A few hundred bytes of YAML whose aliases expand to width ** levels strings."""
    lines = ['a0: &a0 ["xxxxxxxx"]']
    for level in range(1, levels + 1):
        lines.append(f"a{level}: &a{level} [" + ", ".join([f"*a{level - 1}"] * width) + "]")
    lines += [f"image: *a{levels}", "resolution: 0.05", "origin: [0.0, 0.0, 0.0]", "negate: 0",
              "occupied_thresh: 0.65", "free_thresh: 0.196"]
    return ("\n".join(lines) + "\n").encode()


def refusal_of(content, tmp_path, name="map.yaml"):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(MapFileError) as refused:
        load_map(tmp_path / name)
    message = str(refused.value)
    assert "\n" not in message and len(message) < 400, message
    return message


@pytest.mark.timeout(20)
def test_a_yaml_alias_bomb_is_refused_before_it_expands(tmp_path):
    assert len(alias_bomb()) < 600
    assert "alias" in refusal_of(alias_bomb(), tmp_path)


@pytest.mark.parametrize("content, reason", [
    (b"image: " + b"[" * 20000 + b"]" * 20000 + b"\n", "nesting deeper than"),
    (b"image: map.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: " + b"7" * 5000
     + b"\noccupied_thresh: 0.65\nfree_thresh: 0.196\n", "negate|usable YAML"),
    (b"image: map.pgm\nresolution: 1" + b"0" * 400 + b"\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
     b"occupied_thresh: 0.65\nfree_thresh: 0.196\n", "resolution must be a number|usable YAML"),
    (b"image: [unclosed\n", "not valid YAML: .* at line"),
])
def test_hostile_yaml_is_refused_in_one_line_not_a_traceback(tmp_path, content, reason):
    assert re.search(reason, refusal_of(content, tmp_path))


def test_a_yaml_over_the_size_limit_is_refused_unread(tmp_path):
    content = b"image: map.pgm\n" + b"# padding\n" * (map_files.MAX_YAML_BYTES // 10 + 1)
    assert "over the limit" in refusal_of(content, tmp_path)


@pytest.mark.parametrize("content, reason", [
    (b"P5\n99999999999999999999 1\n255\n\x00", "over the limit"),
    (b"P5\n3000 3000\n255\n", "over the limit"),
    (b"P2\n1 1\n255\n99999999999999999999\n", "above 8 bits"),
    (b"P2\n1 1\n255\n-3\n", "negative sample"),
    (b"P5\n1" + b"0" * 30 + b" 1\n255\n\x00", "malformed header"),
])
def test_hostile_images_are_refused_in_one_line_before_their_pixels_are_read(tmp_path, content, reason):
    (tmp_path / "map.pgm").write_bytes(content)
    write_yaml(tmp_path / "a.yaml")
    assert re.search(reason, refusal_of((tmp_path / "a.yaml").read_bytes(), tmp_path, "a.yaml"))


def test_an_image_over_the_file_size_limit_is_refused_unread(tmp_path):
    with open(tmp_path / "map.pgm", "wb") as stream:
        stream.write(b"P5\n1 1\n255\n")
        stream.truncate(map_files.MAX_IMAGE_BYTES + 1)
    write_yaml(tmp_path / "a.yaml")
    assert "over the limit" in refusal_of((tmp_path / "a.yaml").read_bytes(), tmp_path, "a.yaml")


def test_a_fifo_for_an_image_is_refused_not_waited_on(tmp_path):
    os.mkfifo(tmp_path / "map.pgm")
    write_yaml(tmp_path / "a.yaml")
    assert "not a regular file" in refusal_of((tmp_path / "a.yaml").read_bytes(), tmp_path, "a.yaml")


@pytest.mark.parametrize("origin", [(-10.0, 1.0e-05, 0.0), (1e16, -2.5e-300, 3.0)])
def test_origins_with_exponents_are_written_as_yaml_floats_and_read_back(tmp_path, origin):
    original = OccupancyMap(np.zeros((2, 3), dtype=np.int8), 1e-3, origin)
    assert load_map(save_map(original, tmp_path / "m")[0]) == original


def test_the_size_is_read_from_the_header_and_a_short_file_is_truncated(tmp_path):
    (tmp_path / "map.pgm").write_bytes(b"P5\n# a comment\n7 5\n255\n" + bytes(35))
    assert map_files.pnm_size(tmp_path / "map.pgm") == (7, 5)
    (tmp_path / "map.pgm").write_bytes(b"P5\n# a comment\n7 5\n255\n" + bytes(34))
    with pytest.raises(MapFileError, match="truncated: 34 of 35"):
        map_files.pnm_size(tmp_path / "map.pgm")


YAML_PIECES = st.sampled_from([
    "image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode", ": ", "\n", "- ", "[",
    "]", "{", "}", ", ", "&a ", "*a", "!!str ", "!!python/object ", "'", '"', "map.pgm", "0.05", "1e-05", "-3",
    "99999999999999999999", "trinary", "raw", "~", "#", "  ", "---\n", "...\n", "? ", "|", ">", "\t", "\x00",
])


def assert_read_or_refused_in_one_line(read, content):
    try:
        read(content)
    except MapFileError as error:
        assert "\n" not in str(error) and len(str(error)) < 400


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=400), st.lists(YAML_PIECES, max_size=60).map(lambda p: "".join(p).encode())))
def test_map_yaml_reader_survives_any_bytes(content):
    assert_read_or_refused_in_one_line(lambda data: map_files.parse_map_description(data, "fuzz.yaml"), content)


PNM_HEADERS = st.builds(
    lambda magic, width, height, maxval, comment: f"{magic}\n{comment}{width} {height}\n{maxval}\n".encode(),
    st.sampled_from(["P2", "P3", "P5", "P6", "P4", "P7"]),
    st.one_of(st.integers(min_value=0, max_value=20), st.integers(min_value=0, max_value=10 ** 25)),
    st.one_of(st.integers(min_value=0, max_value=20), st.integers(min_value=0, max_value=10 ** 25)),
    st.sampled_from([0, 1, 15, 255, 256, 65535, 10 ** 20]),
    st.sampled_from(["", "# comment\n", "#\n"]))


@settings(max_examples=300, deadline=None)
@given(st.one_of(st.binary(max_size=400), st.tuples(PNM_HEADERS, st.binary(max_size=1200)).map(lambda t: t[0] + t[1])))
def test_image_reader_survives_any_bytes(content):
    def read(data):
        pixels = map_files.parse_pnm(data, "fuzz.pgm")
        assert pixels.dtype == np.uint8 and pixels.ndim == 3 and pixels.size <= 3 * map_files.MAX_MAP_CELLS
    assert_read_or_refused_in_one_line(read, content)
