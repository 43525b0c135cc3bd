"""Occupancy maps on disk in ROS map_server's format (a PGM image plus a YAML file).

Pure Python and numpy; no rospy. Public API:

``OccupancyMap(data, resolution, origin)``
    ``data``: ``numpy.int8`` array of shape ``(height, width)``; ``data[row, col]`` is the
    cell at x index ``col``, y index ``row`` -- row 0 is the row at the origin (lowest y),
    exactly ``nav_msgs/OccupancyGrid.data`` reshaped to ``(height, width)``. Values:
    ``-1`` unknown, ``0`` free .. ``100`` occupied. ``resolution``: metres per cell.
    ``origin``: ``(x, y, yaw)`` of the lower-left corner of cell (0, 0) in the map frame.
    Properties ``width``, ``height``; ``grid_message_data()`` gives the flat row-major
    list for ``OccupancyGrid.data``; ``from_message(data, width, height, resolution,
    origin)`` builds one from an ``OccupancyGrid``'s fields.

``save_map(occupancy_map, prefix, occupied_threshold=65, free_threshold=25) -> (yaml_path, pgm_path)``
    Writes ``<prefix>.pgm`` and ``<prefix>.yaml`` as ROS ``map_saver`` does: cells with
    ``0 <= value <= free_threshold`` become 254 (free), ``value >= occupied_threshold`` 0
    (occupied), everything else (unknown, in-between) 205; the top image row is the
    highest y. The YAML names the image by its file name (relative to the YAML's folder,
    so the pair can be moved or renamed together), with ``negate: 0``,
    ``occupied_thresh: 0.65`` and ``free_thresh: 0.196``, which map_server reads back as
    254 -> free, 0 -> occupied and 205 (occupancy 50/255 = 0.19608) -> unknown. Each file
    is written to a temporary name and renamed into place, so a failed save never leaves
    a half-written map behind.

``load_map(yaml_path) -> OccupancyMap``
    Reads any map_server YAML (``image`` absolute or relative to the YAML's folder,
    ``resolution``, ``origin``, ``negate``, ``occupied_thresh``, ``free_thresh``, optional
    ``mode`` trinary | scale | raw) and converts the image cell by cell as map_server's
    loader does. Images: binary and ASCII PGM (P5, P2) and PPM (P6, P3), maxval <= 255.

``MapFileError``
    Raised (a ``ValueError``) for a missing file, a missing or invalid YAML key, an
    unsupported or truncated image; the message names the file and the problem.

``trinary_pixels(data, occupied_threshold, free_threshold)``, ``read_pnm(path)``,
``write_pgm(path, pixels, comment)`` are the building blocks, public for tools and tests;
``write_atomically(path, content)`` replaces a file whole or not at all (also for map_store).
"""
import json
import math
import os
import tempfile

import numpy as np
import yaml

UNKNOWN = -1
FREE = 0
OCCUPIED = 100

FREE_PIXEL = 254
OCCUPIED_PIXEL = 0
UNKNOWN_PIXEL = 205

SAVED_OCCUPIED_THRESH = 0.65
# map_saver's value: 205 reads back as occupancy 50/255 = 0.19608, just above it, so unknown stays
# unknown; 254 reads back as 1/255 = 0.0039, well below it, so free stays free.
SAVED_FREE_THRESH = 0.196

MODES = ("trinary", "scale", "raw")
REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")


class MapFileError(ValueError):
    """A map file that cannot be read or written; the message names the file."""


class OccupancyMap:
    """An occupancy grid with its geometry, as carried by nav_msgs/OccupancyGrid."""

    def __init__(self, data, resolution, origin=(0.0, 0.0, 0.0)):
        data = np.asarray(data)
        if data.ndim != 2:
            raise ValueError(f"occupancy data must be 2-D (height, width), got shape {data.shape}")
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, got {resolution}")
        self.data = data.astype(np.int8)
        self.resolution = float(resolution)
        x, y, yaw = origin
        self.origin = (float(x), float(y), float(yaw))

    @property
    def width(self):
        return self.data.shape[1]

    @property
    def height(self):
        return self.data.shape[0]

    def grid_message_data(self):
        """Row-major cell values for OccupancyGrid.data (row 0 = lowest y)."""
        return self.data.reshape(-1).tolist()

    @classmethod
    def from_message(cls, data, width, height, resolution, origin):
        cells = np.asarray(data, dtype=np.int8)
        if cells.size != width * height:
            raise ValueError(f"occupancy data has {cells.size} cells, expected {width} x {height}")
        return cls(cells.reshape(height, width), resolution, origin)

    def __eq__(self, other):
        return (isinstance(other, OccupancyMap) and self.resolution == other.resolution
                and self.origin == other.origin and np.array_equal(self.data, other.data))

    def __repr__(self):
        return f"OccupancyMap({self.width}x{self.height} @ {self.resolution} m, origin={self.origin})"


# --- saving ---------------------------------------------------------------------------------

def trinary_pixels(data, occupied_threshold=65, free_threshold=25):
    """map_saver's pixel rule, image rows top = highest y."""
    data = np.asarray(data)
    pixels = np.full(data.shape, UNKNOWN_PIXEL, dtype=np.uint8)
    pixels[(data >= 0) & (data <= free_threshold)] = FREE_PIXEL
    pixels[data >= occupied_threshold] = OCCUPIED_PIXEL
    return pixels[::-1]


def validate_thresholds(occupied_threshold, free_threshold):
    """map_saver's limits: occupied in 1..100, free in 0..100, free below occupied."""
    if not 1 <= occupied_threshold <= 100:
        raise ValueError(f"occupied threshold must be between 1 and 100, got {occupied_threshold}")
    if not 0 <= free_threshold <= 100:
        raise ValueError(f"free threshold must be between 0 and 100, got {free_threshold}")
    if not free_threshold < occupied_threshold:
        raise ValueError(
            f"free threshold ({free_threshold}) must be below the occupied threshold ({occupied_threshold})")


def save_map(occupancy_map, prefix, occupied_threshold=65, free_threshold=25):
    """Write <prefix>.pgm and <prefix>.yaml; returns their paths."""
    validate_thresholds(occupied_threshold, free_threshold)
    prefix = os.fspath(prefix)
    pgm_path, yaml_path = prefix + ".pgm", prefix + ".yaml"
    folder = os.path.dirname(os.path.abspath(prefix))
    if not os.path.isdir(folder):
        raise MapFileError(f"cannot save map {prefix}: folder {folder} does not exist")
    pixels = trinary_pixels(occupancy_map.data, occupied_threshold, free_threshold)
    write_pgm(pgm_path, pixels, f"turtlebot3c map {occupancy_map.resolution:.3f} m/pix")
    write_atomically(yaml_path, map_yaml_text(os.path.basename(pgm_path), occupancy_map).encode())
    return yaml_path, pgm_path


def map_yaml_text(image_name, occupancy_map):
    x, y, yaw = occupancy_map.origin
    return (f"image: {_yaml_scalar(image_name)}\n"
            f"resolution: {occupancy_map.resolution!r}\n"
            f"origin: [{x!r}, {y!r}, {yaw!r}]\n"
            "negate: 0\n"
            f"occupied_thresh: {SAVED_OCCUPIED_THRESH}\n"
            f"free_thresh: {SAVED_FREE_THRESH}\n")


def _yaml_scalar(text):
    """A plain file name as is; anything else double-quoted (a JSON string is a valid YAML scalar)."""
    plain = text and all(c.isalnum() or c in "-_." for c in text) and text[0] not in "-."
    return text if plain else json.dumps(text)


def write_pgm(path, pixels, comment=""):
    """Binary PGM (P5, maxval 255), rows as given (top row first)."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    height, width = pixels.shape
    header = f"P5\n# {comment}\n{width} {height}\n255\n" if comment else \
        f"P5\n{width} {height}\n255\n"
    write_atomically(os.fspath(path), header.encode() + pixels.tobytes())


def write_atomically(path, content):
    """Write `content` (bytes) to a temporary file beside `path`, flushed to disk, then rename it to `path`:
    readers see the old file or the new one whole, even after a crash; a failure leaves no temporary behind."""
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(content)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise


# --- loading --------------------------------------------------------------------------------

def load_map(yaml_path):
    """Read a map_server YAML and its image into an OccupancyMap, cell for cell as map_server."""
    yaml_path = os.fspath(yaml_path)
    description = _read_yaml(yaml_path)
    image_path = _image_path(yaml_path, description["image"])
    channels = read_pnm(image_path)
    data = image_to_occupancy(channels, description["negate"], description["occupied_thresh"],
                              description["free_thresh"], description["mode"])
    return OccupancyMap(data, description["resolution"], description["origin"])


def read_map_description(yaml_path):
    """The validated keys of a map YAML (``mode`` filled in as map_server would)."""
    return _read_yaml(os.fspath(yaml_path))


def _read_yaml(yaml_path):
    try:
        with open(yaml_path, "rb") as stream:
            document = yaml.safe_load(stream)
    except OSError as error:
        raise MapFileError(f"cannot read map file {yaml_path}: {error.strerror or error}") from error
    except yaml.YAMLError as error:
        raise MapFileError(f"map file {yaml_path} is not valid YAML: {error}") from error
    if not isinstance(document, dict):
        raise MapFileError(f"map file {yaml_path} is not a YAML mapping of map_server keys")
    missing = [key for key in REQUIRED_KEYS if key not in document]
    if missing:
        raise MapFileError("map file {} lacks the key(s) {} (map_server needs {})".format(
            yaml_path, ", ".join(missing), ", ".join(REQUIRED_KEYS)))

    def number(key):
        value = document[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise MapFileError(f"map file {yaml_path}: {key} must be a number, got {value!r}")
        return float(value)

    image = document["image"]
    if not isinstance(image, str) or not image:
        raise MapFileError(f"map file {yaml_path}: image must be a non-empty file name, got {image!r}")
    resolution = number("resolution")
    if resolution <= 0:
        raise MapFileError(f"map file {yaml_path}: resolution must be positive, got {resolution}")
    origin = document["origin"]
    if not isinstance(origin, (list, tuple)) or len(origin) != 3 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in origin):
        raise MapFileError(f"map file {yaml_path}: origin must be [x, y, yaw] numbers, got {origin!r}")
    negate = document["negate"]
    if isinstance(negate, bool) or not isinstance(negate, int):
        raise MapFileError(f"map file {yaml_path}: negate must be an integer (0 or 1), got {negate!r}")
    mode = document.get("mode", "trinary")
    if mode not in MODES:
        raise MapFileError("map file {}: mode {!r} is not one of {}".format(yaml_path, mode, ", ".join(MODES)))
    return {
        "image": image, "resolution": resolution, "origin": tuple(float(v) for v in origin),
        "negate": negate, "occupied_thresh": number("occupied_thresh"), "free_thresh": number("free_thresh"),
        "mode": mode,
    }


def _image_path(yaml_path, image):
    if os.path.isabs(image):
        return image
    return os.path.join(os.path.dirname(os.path.abspath(yaml_path)), image)


def image_to_occupancy(channels, negate, occupied_thresh, free_thresh, mode="trinary"):
    """map_server's per-pixel conversion of an image (rows top first, shape (h, w, n)) to cells."""
    channels = np.asarray(channels, dtype=np.float64)
    count = channels.shape[2]
    # map_server takes the last channel as alpha whenever there is more than one: for RGB
    # images that is blue, so a pure-blue-free pixel counts as transparent in scale mode.
    alpha = channels[:, :, -1] if count > 1 else np.ones(channels.shape[:2])
    color = channels.sum(axis=2) / count
    if negate:
        color = 255.0 - color
    if mode == "raw":
        cells = np.floor(color).astype(np.uint8).view(np.int8)
        return cells[::-1]
    occupancy = (255.0 - color) / 255.0
    cells = np.empty(color.shape, dtype=np.int8)
    middle = ~((occupancy > occupied_thresh) | (occupancy < free_thresh))
    if mode == "scale":
        ratio = (occupancy - free_thresh) / (occupied_thresh - free_thresh)
        scaled = np.floor(1.0 + 98.0 * np.where(middle, ratio, 0.0)).astype(np.int8)
        cells[:] = np.where(alpha < 1.0, UNKNOWN, scaled)
    else:
        cells[:] = UNKNOWN
    cells[occupancy > occupied_thresh] = OCCUPIED
    cells[(occupancy < free_thresh) & ~(occupancy > occupied_thresh)] = FREE
    return cells[::-1]


def read_pnm(path):
    """Pixels of a PGM/PPM file (P2, P3, P5, P6) as uint8 array (rows top first, channels last).

    Samples are scaled to 0..255 when maxval is below 255, as SDL_image (map_server's image
    library) does.
    """
    path = os.fspath(path)
    try:
        with open(path, "rb") as stream:
            content = stream.read()
    except OSError as error:
        raise MapFileError(f"cannot read map image {path}: {error.strerror or error}") from error
    magic = content[:2]
    if magic not in (b"P2", b"P3", b"P5", b"P6"):
        raise MapFileError(f"map image {path} is not a PGM/PPM file (P2, P3, P5 or P6); starts with {content[:8]!r}")
    channels = 3 if magic in (b"P3", b"P6") else 1
    fields, position = _pnm_header(path, content)
    width, height, maxval = fields
    if width <= 0 or height <= 0:
        raise MapFileError(f"map image {path} has an empty size {width} x {height}")
    if not 0 < maxval <= 255:
        raise MapFileError(f"map image {path}: maxval {maxval} unsupported (8-bit images only, maxval 1..255)")
    count = width * height * channels
    if magic in (b"P5", b"P6"):
        body = content[position + 1:position + 1 + count]
        if len(body) < count:
            raise MapFileError(f"map image {path} is truncated: {len(body)} of {count} pixel bytes")
        samples = np.frombuffer(body, dtype=np.uint8).astype(np.int64)
    else:
        try:
            samples = np.array(_strip_comments(content[position:]).split()[:count + 1], dtype=np.int64)
        except ValueError:
            raise MapFileError(f"map image {path} has a non-numeric sample") from None
        if samples.size < count:
            raise MapFileError(f"map image {path} is truncated: {samples.size} of {count} samples")
        samples = samples[:count]
    if samples.max(initial=0) > maxval:
        raise MapFileError(f"map image {path} has samples above its maxval {maxval}")
    if maxval < 255:
        samples = samples * 255 // maxval
    return samples.astype(np.uint8).reshape(height, width, channels)


def _strip_comments(text):
    return b"\n".join(line.split(b"#", 1)[0] for line in text.split(b"\n"))


def _pnm_header(path, content):
    """width, height, maxval and the index of the single whitespace byte that ends the header."""
    fields, position, size = [], 2, len(content)
    while len(fields) < 3:
        while position < size and (content[position:position + 1].isspace() or content[position] == ord("#")):
            if content[position] == ord("#"):
                end = content.find(b"\n", position)
                position = size if end < 0 else end
            position += 1
        start = position
        while position < size and content[position:position + 1].isdigit():
            position += 1
        if start == position:
            raise MapFileError(f"map image {path} has a malformed header (need width, height, maxval)")
        fields.append(int(content[start:position]))
    if position >= size or not content[position:position + 1].isspace():
        raise MapFileError(f"map image {path} has a malformed header after maxval")
    return fields, position
