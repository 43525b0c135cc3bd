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
    unsupported or truncated image, a file over the limits below; the message is one
    line naming the file and the problem.

Limits, checked before anything big is read or allocated, so that no file (a map given to
the owner to import, one left in the map folder) costs unbounded memory or time: a YAML
file of at most ``MAX_YAML_BYTES``, nested at most ``MAX_YAML_DEPTH`` deep, with no aliases
(map_server's keys need none, and an alias bomb of a few hundred bytes expands to
gigabytes); an image of at most ``MAX_IMAGE_BYTES`` and ``MAX_MAP_CELLS`` cells.
``parse_map_description(content, name)`` and ``parse_pnm(content, name)`` read bytes already
in memory (the map store reads files through descriptors it opened itself).

``trinary_pixels(data, occupied_threshold, free_threshold)``, ``read_pnm(path)``,
``pnm_size(path)`` (width, height from the header only), ``shown(value)`` (a value, short, for
a message), ``write_pgm(path, pixels, comment)`` and ``map_yaml(description)`` are the
building blocks, public for tools and tests;
``write_atomically(path, content)`` replaces a file whole or not at all (also for map_store).
"""
import json
import os
import stat
import tempfile

import numpy as np
import yaml

from turtlebot3c_common.parameter_files import is_finite_number

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

# A map_server YAML is some 200 bytes of one mapping; an image of 2000 x 2000 cells is 100 m x 100 m
# at 5 cm, beyond any TurtleBot3 LIDAR's building, and loads in some 150 MB.
MAX_YAML_BYTES = 64 * 1024
MAX_YAML_DEPTH = 8
MAX_MAP_CELLS = 4000000
MAX_IMAGE_BYTES = 16 * 1024 * 1024
MAX_PNM_HEADER_BYTES = 4096
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
    description = {"image": os.path.basename(pgm_path), "resolution": occupancy_map.resolution,
                   "origin": occupancy_map.origin, "negate": 0, "occupied_thresh": SAVED_OCCUPIED_THRESH,
                   "free_thresh": SAVED_FREE_THRESH}
    write_atomically(yaml_path, map_yaml(description).encode())
    return yaml_path, pgm_path


def map_yaml(description):
    """map_server YAML text for validated keys (as read_map_description returns them)."""
    x, y, yaw = description["origin"]
    text = (f"image: {_yaml_scalar(description['image'])}\n"
            f"resolution: {_yaml_float(description['resolution'])}\n"
            f"origin: [{_yaml_float(x)}, {_yaml_float(y)}, {_yaml_float(yaw)}]\n"
            f"negate: {int(description['negate'])}\n"
            f"occupied_thresh: {_yaml_float(description['occupied_thresh'])}\n"
            f"free_thresh: {_yaml_float(description['free_thresh'])}\n")
    if description.get("mode", "trinary") != "trinary":
        text += f"mode: {description['mode']}\n"
    return text


def _yaml_float(value):
    """A float YAML 1.1 reads back as that float: PyYAML (and yaml-cpp's map_server) take `1e-05` for a
    string, so an exponent gets a mantissa with a point (`1.0e-05`)."""
    text = repr(float(value))
    mantissa, exponent = text.split("e") if "e" in text else (text, None)
    if exponent is not None and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


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
    description = read_map_description(yaml_path)
    image_path = _image_path(yaml_path, description["image"])
    return occupancy_map_of(description, read_pnm(image_path))


def occupancy_map_of(description, channels):
    """The map a validated description and its image's pixels (from read_pnm / parse_pnm) make."""
    data = image_to_occupancy(channels, description["negate"], description["occupied_thresh"],
                              description["free_thresh"], description["mode"])
    return OccupancyMap(data, description["resolution"], description["origin"])


def read_map_description(yaml_path):
    """The validated keys of a map YAML (``mode`` filled in as map_server would)."""
    yaml_path = os.fspath(yaml_path)
    return parse_map_description(read_bounded(yaml_path, MAX_YAML_BYTES, "map file"), yaml_path)


def read_bounded(path, limit, what):
    """The content of the regular file at `path` (links followed), refused unread when over `limit` bytes.
    Opened without blocking, so a FIFO or a device is refused rather than waited on or read for ever."""
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as error:
        raise MapFileError(f"cannot read {what} {path}: {error.strerror or error}") from None
    with os.fdopen(descriptor, "rb") as stream:
        return read_stream_bounded(stream, path, limit, what)


def read_stream_bounded(stream, path, limit, what):
    """The content of an open regular file, refused when over `limit` bytes (checked before and while reading)."""
    status = os.fstat(stream.fileno())
    if not stat.S_ISREG(status.st_mode):
        raise MapFileError(f"{what} {path} is not a regular file")
    if status.st_size > limit:
        raise MapFileError(f"{what} {path} has {status.st_size} bytes, over the limit of {limit}")
    try:
        content = stream.read(limit + 1)
    except OSError as error:
        raise MapFileError(f"cannot read {what} {path}: {error.strerror or error}") from None
    if len(content) > limit:
        raise MapFileError(f"{what} {path} grew over the limit of {limit} bytes while read")
    return content


class _MapYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader without aliases and with a nesting limit: map_server's keys need neither,
    and both let a few hundred bytes cost unbounded memory, time or stack."""

    _depth = 0

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            raise yaml.composer.ComposerError(None, None, "an alias (*name), which map files may not use",
                                              self.peek_event().start_mark)
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nesting deeper than {MAX_YAML_DEPTH} levels",
                                                  self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1


def _load_yaml(content, path):
    loader = None
    try:
        loader = _MapYamlLoader(content)  # which already decodes and checks the characters
        return loader.get_single_data()
    except yaml.MarkedYAMLError as error:
        where = f" at line {error.problem_mark.line + 1}" if error.problem_mark else ""
        raise MapFileError(f"map file {path} is not valid YAML: {error.problem}{where}") from None
    except yaml.YAMLError as error:
        raise MapFileError(f"map file {path} is not valid YAML: {_one_line(error)}") from None
    except (ValueError, OverflowError, RecursionError) as error:  # a number too long for Python, say
        raise MapFileError(f"map file {path} is not a usable YAML file: {shown(str(error))}") from None
    finally:
        if loader is not None:
            loader.dispose()


def parse_map_description(content, path):
    """The validated keys of map YAML text `content` (bytes); `path` names it in errors."""
    document = _load_yaml(content, path)
    if not isinstance(document, dict):
        raise MapFileError(f"map file {path} is not a YAML mapping of map_server keys")
    missing = [key for key in REQUIRED_KEYS if key not in document]
    if missing:
        raise MapFileError("map file {} lacks the key(s) {} (map_server needs {})".format(
            path, ", ".join(missing), ", ".join(REQUIRED_KEYS)))

    def number(key):
        value = document[key]
        if not is_finite_number(value):
            raise MapFileError(f"map file {path}: {key} must be a number, got {shown(value)}")
        return float(value)

    image = document["image"]
    if not isinstance(image, str) or not image:
        raise MapFileError(f"map file {path}: image must be a non-empty file name, got {shown(image)}")
    resolution = number("resolution")
    if resolution <= 0:
        raise MapFileError(f"map file {path}: resolution must be positive, got {resolution}")
    origin = document["origin"]
    if not isinstance(origin, (list, tuple)) or len(origin) != 3 or not all(is_finite_number(v) for v in origin):
        raise MapFileError(f"map file {path}: origin must be [x, y, yaw] numbers, got {shown(origin)}")
    negate = document["negate"]
    if isinstance(negate, bool) or not isinstance(negate, int) or negate not in (0, 1):
        raise MapFileError(f"map file {path}: negate must be an integer (0 or 1), got {shown(negate)}")
    mode = document.get("mode", "trinary")
    if mode not in MODES:
        raise MapFileError("map file {}: mode {} is not one of {}".format(path, shown(mode), ", ".join(MODES)))
    return {
        "image": image, "resolution": resolution, "origin": tuple(float(v) for v in origin),
        "negate": negate,
        "occupied_thresh": number("occupied_thresh"), "free_thresh": number("free_thresh"), "mode": mode,
    }


def shown(value, limit=60):
    """A value for an error message: short, one line, and cheap whatever the file held."""
    if isinstance(value, (list, tuple)) and len(value) > 8:
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return f"a mapping of {len(value)} keys"
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return "an integer of more than 19 digits"
    try:
        text = repr(value)
    except (ValueError, RecursionError):
        return f"a {type(value).__name__}"
    text = _one_line(text)
    return text if len(text) <= limit else text[:limit] + "..."


def _one_line(text):
    return " ".join(str(text).split())


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
    return parse_pnm(read_bounded(path, MAX_IMAGE_BYTES, "map image"), path)


def pnm_size(path):
    """(width, height) of a PGM/PPM file from its header alone, checked against the limits; a binary
    image shorter than its header says is refused as truncated (from its size, unread)."""
    path = os.fspath(path)
    try:
        with open(path, "rb") as stream:
            head = stream.read(MAX_PNM_HEADER_BYTES)
            size = os.fstat(stream.fileno()).st_size
    except OSError as error:
        raise MapFileError(f"cannot read map image {path}: {error.strerror or error}") from None
    width, height, _, position = _pnm_layout(path, head)
    if head[:2] in (b"P5", b"P6"):
        count = width * height * (3 if head[:2] == b"P6" else 1)
        if size < position + 1 + count:
            raise MapFileError(f"map image {path} is truncated: {max(size - position - 1, 0)} of {count} pixel bytes")
    return width, height


def parse_pnm(content, path):
    """Pixels of PGM/PPM file content (bytes), as read_pnm; `path` names it in errors."""
    width, height, maxval, position = _pnm_layout(path, content)
    channels = 3 if content[:2] in (b"P3", b"P6") else 1
    count = width * height * channels
    if content[:2] in (b"P5", b"P6"):
        body = content[position + 1:position + 1 + count]
        if len(body) < count:
            raise MapFileError(f"map image {path} is truncated: {len(body)} of {count} pixel bytes")
        samples = np.frombuffer(body, dtype=np.uint8).astype(np.int64)
    else:
        try:
            samples = np.array(_strip_comments(content[position:]).split()[:count + 1], dtype=np.int64)
        except ValueError:
            raise MapFileError(f"map image {path} has a non-numeric sample") from None
        except OverflowError:
            raise MapFileError(f"map image {path} has a sample above 8 bits") from None
        if samples.size < count:
            raise MapFileError(f"map image {path} is truncated: {samples.size} of {count} samples")
        samples = samples[:count]
    if samples.max(initial=0) > maxval:
        raise MapFileError(f"map image {path} has samples above its maxval {maxval}")
    if samples.min(initial=0) < 0:
        raise MapFileError(f"map image {path} has a negative sample")
    if maxval < 255:
        samples = samples * 255 // maxval
    return samples.astype(np.uint8).reshape(height, width, channels)


def _pnm_layout(path, content):
    """width, height, maxval and the index of the byte that ends the header, all checked against the limits
    before a single pixel is read."""
    magic = content[:2]
    if magic not in (b"P2", b"P3", b"P5", b"P6"):
        raise MapFileError(f"map image {path} is not a PGM/PPM file (P2, P3, P5 or P6); starts with {content[:8]!r}")
    (width, height, maxval), position = _pnm_header(path, content)
    if width <= 0 or height <= 0:
        raise MapFileError(f"map image {path} has an empty size {width} x {height}")
    if width * height > MAX_MAP_CELLS:
        raise MapFileError(f"map image {path} has {_count(width)} x {_count(height)} cells, over the limit of"
                           f" {MAX_MAP_CELLS}")
    if not 0 < maxval <= 255:
        raise MapFileError(f"map image {path}: maxval {_count(maxval)} unsupported (8-bit images only, maxval 1..255)")
    return width, height, maxval, position


def _count(number):
    return str(number) if number.bit_length() <= 64 else "more than 10^19"


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
        while position < size and content[position:position + 1].isdigit() and position - start < 20:
            position += 1
        if start == position or (position < size and content[position:position + 1].isdigit()):
            raise MapFileError(f"map image {path} has a malformed header (need width, height, maxval"
                               " of at most 20 digits)")
        fields.append(int(content[start:position]))
    if position >= size or not content[position:position + 1].isspace():
        raise MapFileError(f"map image {path} has a malformed header after maxval")
    return fields, position
