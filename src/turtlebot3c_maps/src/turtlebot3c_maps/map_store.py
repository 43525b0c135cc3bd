"""The snap's map folder: every map kept, listed, previewed, renamed, removed, exported and imported.

Pure Python (no rospy), Python 3.8 / numpy 1.17. The folder ($SNAP_COMMON/maps in the snap)
holds, per map NAME: ``NAME.yaml`` (map_server's format, naming its image relatively),
``NAME.pgm`` and, when mapping recorded the session, ``NAME.bag`` (or ``NAME.bag.active``).
``current_map.yaml`` is a relative link to the map navigation uses; it is only ever
replaced by rename(2). ``new_map.*`` are the mapping daemon's files in transit and hidden
files (``.NAME``) are work in progress: neither is a map.

A map's date is its image's modification time: set when the map is saved or imported,
kept by rename, export and migration. So the newest map is the one added last.

Public API: ``MapStore(folder)`` with ``maps()``, ``get(name)``, ``current_name()``,
``set_current(name)``, ``rename(old, new)``, ``remove(name)``, ``export(name, folder)``,
``import_map(path, name=None)``; ``write_preview(occupancy_map, path)`` and
``encode_png(pixels)``; ``check_name(name)``; ``MapStoreError`` (a ValueError whose
message says what is wrong and what to do).
"""
import contextlib
import fcntl
import os
import shutil
import struct
import tempfile
import zlib

import numpy as np

from turtlebot3c_maps import map_files

CURRENT = "current_map"
IN_TRANSIT = "new_map"
RESERVED_NAMES = (CURRENT, IN_TRANSIT, "latest")
NAME_CHARACTERS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-")
MAX_NAME_LENGTH = 100
BAG_MAGIC = b"#ROSBAG V2.0\n"
PGM_MAGICS = (b"P5", b"P2")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class MapStoreError(ValueError):
    """A map operation that cannot be done; the message says why and what to do."""


def check_name(name):
    """A name a map may get: letters, digits, '.', '_', '-', not starting with '.' or '-', not reserved."""
    if not name or len(name) > MAX_NAME_LENGTH or not set(name) <= NAME_CHARACTERS or name[0] in ".-":
        raise MapStoreError(
            f"'{name}' cannot name a map: use up to {MAX_NAME_LENGTH} letters, digits, '.', '_' or '-',"
            " not starting with '.' or '-'")
    if name in RESERVED_NAMES or name.endswith(".yaml"):
        raise MapStoreError(f"'{name}' cannot name a map: {', '.join(RESERVED_NAMES)} and *.yaml are reserved")
    return name


class MapInfo:
    """What `list` shows of one map; `problem` is set (and sizes are None) when it cannot be read."""

    def __init__(self, name, modified, width=None, height=None, resolution=None, problem=None, has_bag=False):
        self.name = name
        self.modified = modified
        self.width = width
        self.height = height
        self.resolution = resolution
        self.problem = problem
        self.has_bag = has_bag

    @property
    def size_metres(self):
        if self.problem:
            return None
        return (self.width * self.resolution, self.height * self.resolution)

    def as_dict(self, current):
        metres = self.size_metres
        width_m, height_m = (round(metres[0], 6), round(metres[1], 6)) if metres else (None, None)
        return {"name": self.name, "modified": self.modified, "width": self.width, "height": self.height,
                "resolution": self.resolution, "width_m": width_m, "height_m": height_m,
                "current": self.name == current, "bag": self.has_bag, "problem": self.problem}


class MapStore:
    def __init__(self, folder):
        self.folder = os.fspath(folder)

    # --- reading -------------------------------------------------------------------------

    def path(self, name, suffix=".yaml"):
        return os.path.join(self.folder, name + suffix)

    def names(self):
        """Every map's name, sorted (what the configure hook lists too: *.yaml but the link and new_map)."""
        try:
            entries = os.listdir(self.folder)
        except FileNotFoundError:
            return []
        names = []
        for entry in entries:
            name = entry[:-len(".yaml")]
            if entry.endswith(".yaml") and not entry.startswith(".") and name not in (CURRENT, IN_TRANSIT) \
                    and os.path.isfile(os.path.join(self.folder, entry)):
                names.append(name)
        return sorted(names)

    def current_name(self):
        """The map current_map.yaml links to, or None."""
        try:
            target = os.readlink(self.path(CURRENT))
        except OSError:
            return None
        name = os.path.basename(target)
        return name[:-len(".yaml")] if name.endswith(".yaml") else name

    def require(self, name):
        if name not in self.names():
            known = ", ".join(self.names()) or "none yet"
            raise MapStoreError(f"there is no map '{name}' in {self.folder} (maps: {known})")
        return name

    def get(self, name):
        """MapInfo of one map, read from its YAML and image."""
        self.require(name)
        image = self.path(name, ".pgm")
        try:
            modified = os.stat(image).st_mtime
        except OSError:
            modified = os.stat(self.path(name)).st_mtime
        has_bag = os.path.exists(self.path(name, ".bag")) or os.path.exists(self.path(name, ".bag.active"))
        try:
            description = map_files.read_map_description(self.path(name))
            pixels = map_files.read_pnm(self._image_of(name, description))
        except (map_files.MapFileError, MapStoreError) as error:
            return MapInfo(name, modified, problem=str(error), has_bag=has_bag)
        height, width = pixels.shape[:2]
        return MapInfo(name, modified, width, height, description["resolution"], has_bag=has_bag)

    def maps(self):
        return [self.get(name) for name in self.names()]

    def load(self, name):
        """The map as an OccupancyMap (for previews)."""
        self.require(name)
        description = map_files.read_map_description(self.path(name))
        self._image_of(name, description)
        return map_files.load_map(self.path(name))

    def _image_of(self, name, description):
        image = description["image"]
        if not _plain_file_name(image):
            raise MapStoreError(f"map {name}: its image {image!r} is not a file beside its YAML")
        return os.path.join(self.folder, image)

    # --- changing ------------------------------------------------------------------------

    @contextlib.contextmanager
    def changing(self):
        """Hold the folder's lock for a change; leftovers of interrupted imports are cleared first."""
        os.makedirs(self.folder, mode=0o755, exist_ok=True)
        with open(os.path.join(self.folder, ".lock"), "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            for entry in os.listdir(self.folder):
                if entry.startswith(".import."):
                    shutil.rmtree(os.path.join(self.folder, entry), ignore_errors=True)
            yield

    def set_current(self, name):
        """Point current_map.yaml at the map in one rename(2)."""
        self.require(name)
        temporary = os.path.join(self.folder, f".{CURRENT}.yaml.{os.getpid()}.tmp")
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)
        os.symlink(name + ".yaml", temporary)
        os.replace(temporary, self.path(CURRENT))
        _sync_folder(self.folder)

    def rename(self, old, new):
        """Give map `old` the name `new` (its image and bag too); the current link follows it."""
        self.require(old)
        check_name(new)
        self._refuse_taken(new)
        description = map_files.read_map_description(self.path(old))
        image = self._image_of(old, description)
        moved = []
        try:
            _link_new(image, self.path(new, ".pgm"))
            moved.append(self.path(new, ".pgm"))
            for suffix in (".bag", ".bag.active"):
                if os.path.exists(self.path(old, suffix)):
                    _link_new(self.path(old, suffix), self.path(new, suffix))
                    moved.append(self.path(new, suffix))
            self._write_yaml(new, description)
        except BaseException:
            for path in moved:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            raise
        if self.current_name() == old:
            self.set_current(new)
        for path in [self.path(old), image, self.path(old, ".bag"), self.path(old, ".bag.active")]:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)
        _sync_folder(self.folder)

    def remove(self, name):
        """Delete a map (YAML first: from then on it is no map), never the current one."""
        self.require(name)
        if self.current_name() == name:
            raise MapStoreError(
                f"map {name} is the current map and stays: choose another first"
                " (sudo snap set turtlebot3c map=<name>), then remove it")
        image = self.path(name, ".pgm")
        with contextlib.suppress(map_files.MapFileError, MapStoreError):
            image = self._image_of(name, map_files.read_map_description(self.path(name)))
        for path in [self.path(name), image, self.path(name, ".bag"), self.path(name, ".bag.active")]:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(path)
        _sync_folder(self.folder)

    def export(self, name, folder, with_bag=False):
        """Copy the map to `folder` as NAME.yaml + NAME.pgm (+ NAME.bag); returns the YAML's path."""
        self.require(name)
        if not os.path.isdir(folder):
            raise MapStoreError(f"cannot export to {folder}: no such folder")
        description = map_files.read_map_description(self.path(name))
        image = self._image_of(name, description)
        targets = [os.path.join(folder, name + ".yaml"), os.path.join(folder, name + ".pgm")]
        bag = self.path(name, ".bag")
        if with_bag:
            if not os.path.exists(bag):
                raise MapStoreError(f"map {name} has no session bag to export")
            targets.append(os.path.join(folder, name + ".bag"))
        taken = [target for target in targets if os.path.lexists(target)]
        if taken:
            raise MapStoreError(f"cannot export {name}: {', '.join(taken)} already exist(s); nothing was written")
        if with_bag:
            _copy_new(bag, targets[2])
        _copy_new(image, targets[1])
        description = dict(description, image=name + ".pgm")
        _write_new(targets[0], map_yaml(description).encode())
        return targets[0]

    def import_map(self, source, name=None):
        """Add the map at `source` (its YAML, or a folder holding one) after checking it; returns its name.

        The YAML must be map_server's, its image a PGM file beside it (no path, no link); a
        session bag NAME.bag beside it comes too. Everything is copied into a hidden staging
        folder, checked there, then linked into place image first and YAML last, so a
        rejected or interrupted import leaves no map behind.
        """
        yaml_path = _find_yaml(source)
        name = check_name(name if name is not None else os.path.basename(yaml_path)[:-len(".yaml")])
        self._refuse_taken(name)
        description = map_files.read_map_description(yaml_path)
        image = description["image"]
        if os.path.isabs(image):
            raise MapStoreError(f"{yaml_path}: image {image!r} is an absolute path; an imported map's image"
                                " must be a file name beside its YAML")
        if not _plain_file_name(image):
            raise MapStoreError(f"{yaml_path}: image {image!r} is not a plain file name beside its YAML"
                                " (no folders, no '..')")
        image_path = os.path.join(os.path.dirname(yaml_path), image)
        _require_regular_file(image_path, f"{yaml_path}: its image {image}")
        bag_path = yaml_path[:-len(".yaml")] + ".bag"
        has_bag = os.path.lexists(bag_path)
        if has_bag:
            _require_regular_file(bag_path, "the session bag")

        os.makedirs(self.folder, mode=0o755, exist_ok=True)
        staging = tempfile.mkdtemp(prefix=".import.", dir=self.folder)
        placed = []
        try:
            staged_image = os.path.join(staging, name + ".pgm")
            shutil.copyfile(image_path, staged_image)
            _require_pgm(staged_image, image_path)
            staged_yaml = os.path.join(staging, name + ".yaml")
            with open(staged_yaml, "wb") as stream:
                stream.write(map_yaml(dict(description, image=name + ".pgm")).encode())
            map_files.load_map(staged_yaml)
            staged = [(staged_image, self.path(name, ".pgm"))]
            if has_bag:
                staged_bag = os.path.join(staging, name + ".bag")
                shutil.copyfile(bag_path, staged_bag)
                with open(staged_bag, "rb") as stream:
                    if stream.read(len(BAG_MAGIC)) != BAG_MAGIC:
                        raise MapStoreError(f"{bag_path} is not a ROS 1 bag (no '#ROSBAG V2.0' header)")
                staged.append((staged_bag, self.path(name, ".bag")))
            staged.append((staged_yaml, self.path(name)))
            for path, _ in staged:
                _sync_file(path)
            for path, target in staged:
                os.chmod(path, 0o644)
                _link_new(path, target)
                placed.append(target)
            _sync_folder(self.folder)
        except map_files.MapFileError as error:
            _unlink_all(placed)
            raise MapStoreError(f"{yaml_path} is not a usable map: {error}") from None
        except BaseException:
            _unlink_all(placed)
            raise
        finally:
            shutil.rmtree(staging, ignore_errors=True)
        return name

    def _refuse_taken(self, name):
        taken = [self.path(name, suffix) for suffix in (".yaml", ".pgm", ".bag", ".bag.active")
                 if os.path.lexists(self.path(name, suffix))]
        if taken:
            raise MapStoreError(f"the name {name} is taken ({', '.join(taken)} exist(s)); choose another")

    def _write_yaml(self, name, description):
        temporary = os.path.join(self.folder, f".{name}.yaml.{os.getpid()}.tmp")
        with open(temporary, "wb") as stream:
            stream.write(map_yaml(dict(description, image=name + ".pgm")).encode())
        _sync_file(temporary)
        os.chmod(temporary, 0o644)
        try:
            _link_new(temporary, self.path(name))
        finally:
            os.unlink(temporary)


def map_yaml(description):
    """map_server YAML text for validated keys (as read_map_description returns them)."""
    x, y, yaw = description["origin"]
    text = (f"image: {description['image']}\n"
            f"resolution: {description['resolution']!r}\n"
            f"origin: [{x!r}, {y!r}, {yaw!r}]\n"
            f"negate: {description['negate']}\n"
            f"occupied_thresh: {description['occupied_thresh']!r}\n"
            f"free_thresh: {description['free_thresh']!r}\n")
    if description.get("mode", "trinary") != "trinary":
        text += f"mode: {description['mode']}\n"
    return text


# --- previews ---------------------------------------------------------------------------

def preview_pixels(occupancy_map, scale=1):
    """Grey levels as map_saver draws them (free white, occupied black, unknown grey), top row = highest y."""
    data = occupancy_map.data.astype(np.int16)
    pixels = np.full(data.shape, map_files.UNKNOWN_PIXEL, dtype=np.uint8)
    known = (data >= 0) & (data <= 100)
    pixels[known] = (254 - (data[known] * 254) // 100).astype(np.uint8)
    pixels = pixels[::-1]
    if scale > 1:
        pixels = np.repeat(np.repeat(pixels, scale, axis=0), scale, axis=1)
    return pixels


def encode_png(pixels):
    """An 8-bit greyscale PNG (no filtering, one IDAT) of a (height, width) uint8 array."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    if pixels.ndim != 2 or pixels.size == 0:
        raise ValueError(f"a preview needs a non-empty 2-D image, got shape {pixels.shape}")
    height, width = pixels.shape
    rows = np.zeros((height, width + 1), dtype=np.uint8)  # each row: filter type 0 (None), then the pixels
    rows[:, 1:] = pixels
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return PNG_SIGNATURE + _png_chunk(b"IHDR", header) + \
        _png_chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + _png_chunk(b"IEND", b"")


def _png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def write_preview(occupancy_map, path, scale=1):
    map_files.write_atomically(os.fspath(path), encode_png(preview_pixels(occupancy_map, scale)))
    return os.fspath(path)


# --- files ------------------------------------------------------------------------------

def _plain_file_name(name):
    return isinstance(name, str) and name not in ("", ".", "..") and "/" not in name and "\\" not in name \
        and "\0" not in name


def _find_yaml(source):
    source = os.fspath(source)
    if os.path.isdir(source):
        found = sorted(entry for entry in os.listdir(source)
                       if entry.endswith(".yaml") and not entry.startswith(".") and entry != CURRENT + ".yaml")
        if len(found) != 1:
            raise MapStoreError(f"{source} holds {len(found)} map YAML files ({', '.join(found) or 'none'});"
                                " give the map's YAML file instead")
        return os.path.join(source, found[0])
    if not os.path.exists(source):
        raise MapStoreError(f"{source}: no such file or folder")
    if not source.endswith(".yaml"):
        raise MapStoreError(f"{source}: give the map's YAML file (NAME.yaml) or a folder holding one")
    return source


def _require_regular_file(path, what):
    try:
        mode = os.lstat(path).st_mode
    except OSError:
        raise MapStoreError(f"{what} ({path}) does not exist") from None
    if not (mode & 0o170000) == 0o100000:
        raise MapStoreError(f"{what} ({path}) is not a regular file (links and devices are refused)")


def _require_pgm(staged, original):
    with open(staged, "rb") as stream:
        magic = stream.read(2)
    if magic not in PGM_MAGICS:
        raise MapStoreError(f"{original} is not a PGM image (P5 or P2); it starts with {magic!r}")
    try:
        map_files.read_pnm(staged)
    except map_files.MapFileError as error:
        raise MapStoreError(str(error).replace(staged, original)) from None


def _link_new(source, target):
    """Give `source` the name `target` too, failing if `target` exists (link(2) never replaces)."""
    try:
        os.link(source, target)
    except FileExistsError:
        raise MapStoreError(f"{target} already exists; nothing was replaced") from None


def _copy_new(source, target):
    temporary = target + ".part"
    shutil.copyfile(source, temporary)
    shutil.copystat(source, temporary)
    try:
        _sync_file(temporary)
        _link_new(temporary, target)
    finally:
        os.unlink(temporary)


def _write_new(target, content):
    temporary = target + ".part"
    with open(temporary, "wb") as stream:
        stream.write(content)
    try:
        _sync_file(temporary)
        _link_new(temporary, target)
    finally:
        os.unlink(temporary)


def _unlink_all(paths):
    for path in reversed(paths):
        with contextlib.suppress(OSError):
            os.unlink(path)


def _sync_file(path):
    with open(path, "rb") as stream:
        os.fsync(stream.fileno())


def _sync_folder(folder):
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
