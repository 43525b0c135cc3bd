"""The snap's map folder: every map kept, listed, previewed, renamed, removed, exported and imported.

Pure Python (no rospy), Python 3.8 / numpy 1.17. The folder ($SNAP_COMMON/maps in the snap)
holds, per map NAME: ``NAME.yaml`` (map_server's format, naming its image relatively),
``NAME.pgm`` and, when mapping recorded the session, ``NAME.bag`` (or ``NAME.bag.active``).
``current_map.yaml`` is a relative link to the map navigation uses; it is only ever
replaced by rename(2). ``new_map.*`` are the mapping daemon's files in transit and hidden
files (``.NAME``) are work in progress: neither is a map.

A map is exactly those files: whatever its YAML's ``image:`` says, the store reads, moves,
copies and deletes ``NAME.pgm`` and nothing else, and a YAML naming another image is listed
as a map with a problem (navigation's map_server would load that other file).

A map's date is its image's modification time: set when the map is saved or imported,
kept by rename, export and migration. So the newest map is the one added last.

The ``maps`` app runs changes as root, and export and import reach folders other users
control: there every file is opened once, without following links (``O_NOFOLLOW``), relative
to the folder opened once, and used through that descriptor; what is written there is created
new (``O_EXCL``) and given its final name by link(2), which never replaces anything; what is
read from there must be a regular file within the limits (``MAX_BAG_BYTES`` and map_files'
``MAX_*``) before it is read; an import is staged in a private folder of the store's own.

Public API: ``MapStore(folder)`` with ``maps()``, ``get(name)``, ``load(name)``,
``description(name)`` (its YAML's keys, refused unless its image is NAME.pgm), ``current_name()``,
``set_current(name)``, ``rename(old, new)``, ``remove(name)``, ``export(name, folder)``,
``import_map(path, name=None)``; ``write_preview(occupancy_map, path)`` and
``encode_png(pixels)``; ``check_name(name)``; ``MapStoreError`` (a ValueError whose
message says what is wrong and what to do).
"""
import contextlib
import errno
import fcntl
import os
import secrets
import shutil
import stat
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
# A mapping session records some 100 kB/s (scans, odometry, tf): an hour is well under this.
MAX_BAG_BYTES = 1024 * 1024 * 1024
# A preview of 4000 x 4000 pixels is some 50 MB of work; more is no longer a preview.
MAX_PREVIEW_PIXELS = 16000000
COPY_CHUNK = 1024 * 1024
# Reading a file in a folder someone else controls: never through a link, never waiting on a FIFO.
READ_FLAGS = os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
# Writing there: a new file of our own, never an existing one or a link's target.
CREATE_FLAGS = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC


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
        """MapInfo of one map, from its YAML and its image's header (never the whole image)."""
        self.require(name)
        image = self.path(name, ".pgm")
        modified = _modified(image, self.path(name))
        has_bag = os.path.lexists(self.path(name, ".bag")) or os.path.lexists(self.path(name, ".bag.active"))
        try:
            description = self.description(name)
            width, height = map_files.pnm_size(image)
        except (map_files.MapFileError, MapStoreError) as error:
            return MapInfo(name, modified, problem=str(error), has_bag=has_bag)
        return MapInfo(name, modified, width, height, description["resolution"], has_bag=has_bag)

    def maps(self):
        return [self.get(name) for name in self.names()]

    def load(self, name):
        """The map as an OccupancyMap (for previews)."""
        self.require(name)
        description = self.description(name)
        return map_files.occupancy_map_of(description, map_files.read_pnm(self.path(name, ".pgm")))

    def description(self, name):
        """The validated keys of map `name`'s YAML, refused unless its image is NAME.pgm, a regular file."""
        description = map_files.read_map_description(self.path(name))
        if description["image"] != name + ".pgm":
            raise MapStoreError(f"map {name}: its YAML names the image {map_files.shown(description['image'])},"
                                f" not {name}.pgm")
        image = self.path(name, ".pgm")
        if not _is_regular_file(image):
            raise MapStoreError(f"map {name}: its image {image} is missing or not a regular file")
        return description

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
        description = self.description(old)
        moved = []
        try:
            for suffix in (".pgm", ".bag", ".bag.active"):
                if suffix == ".pgm" or os.path.lexists(self.path(old, suffix)):
                    _link_new(self.path(old, suffix), self.path(new, suffix))
                    moved.append(self.path(new, suffix))
            self._write_yaml(new, description)
        except BaseException:
            _unlink_all(moved)
            raise
        if self.current_name() == old:
            self.set_current(new)
        _unlink_all(self._files_of(old))
        _sync_folder(self.folder)

    def remove(self, name):
        """Delete a map's files (YAML first: from then on it is no map), never the current map's."""
        self.require(name)
        if self.current_name() == name:
            raise MapStoreError(
                f"map {name} is the current map and stays: choose another first"
                " (sudo snap set turtlebot3c map=<name>), then remove it")
        _unlink_all(self._files_of(name))
        _sync_folder(self.folder)

    def _files_of(self, name):
        """Every file of map `name`, the YAML first: never anything its YAML names."""
        return [self.path(name, suffix) for suffix in (".yaml", ".pgm", ".bag", ".bag.active")]

    def export(self, name, folder, with_bag=False):
        """Copy the map to `folder` as NAME.yaml + NAME.pgm (+ NAME.bag); returns the YAML's path.

        `folder` may belong to anyone: each file is created there new under a temporary name and
        linked to its own, so nothing there is overwritten or written through a link."""
        self.require(name)
        description = self.description(name)
        bag = self.path(name, ".bag")
        if with_bag and not _is_regular_file(bag):
            raise MapStoreError(f"map {name} has no session bag to export")
        entries = [name + ".yaml", name + ".pgm"] + ([name + ".bag"] if with_bag else [])
        with _opened_folder(folder, "export to") as target:
            taken = [os.path.join(folder, entry) for entry in entries if _exists_in(target, entry)]
            if taken:
                raise MapStoreError(f"cannot export {name}: {', '.join(taken)} already exist(s); nothing was written")
            written = []
            try:
                if with_bag:
                    written.append(_copy_into(target, name + ".bag", bag))
                written.append(_copy_into(target, name + ".pgm", self.path(name, ".pgm")))
                yaml_text = map_files.map_yaml(dict(description, image=name + ".pgm")).encode()
                written.append(_create_in(target, name + ".yaml", lambda stream: stream.write(yaml_text)))
            except BaseException:
                for entry in written:
                    with contextlib.suppress(OSError):
                        os.unlink(entry, dir_fd=target)
                raise
        return os.path.join(folder, name + ".yaml")

    def import_map(self, source, name=None):
        """Add the map at `source` (its YAML, or a folder holding one) after checking it; returns its name.

        The YAML must be map_server's, its image a PGM file beside it (no path, no link); a
        session bag NAME.bag beside it comes too. Each file is opened once, without following
        links, checked against the limits and read through that descriptor; the copies are
        checked, written into a private staging folder and linked into place image first and
        YAML last, so a rejected or interrupted import leaves no map behind.
        """
        folder, yaml_entry = _split_source(os.fspath(source))
        with _opened_folder(folder, "import from") as origin:
            yaml_entry = yaml_entry or _the_yaml_in(origin, folder)
            name = check_name(name if name is not None else yaml_entry[:-len(".yaml")])
            self._refuse_taken(name)
            description, image = _checked_import(origin, folder, yaml_entry)
            bag_entry = yaml_entry[:-len(".yaml")] + ".bag"
            os.makedirs(self.folder, mode=0o755, exist_ok=True)
            staging = tempfile.mkdtemp(prefix=".import.", dir=self.folder)
            placed = []
            try:
                staged = [(_write_staged(staging, name + ".pgm", image), self.path(name, ".pgm"))]
                if _exists_in(origin, bag_entry):
                    staged_bag = os.path.join(staging, name + ".bag")
                    _copy_bag(origin, bag_entry, os.path.join(folder, bag_entry), staged_bag)
                    staged.append((staged_bag, self.path(name, ".bag")))
                yaml_text = map_files.map_yaml(dict(description, image=name + ".pgm")).encode()
                staged.append((_write_staged(staging, name + ".yaml", yaml_text), self.path(name)))
                for path, target in staged:
                    _link_new(path, target)
                    placed.append(target)
                _sync_folder(self.folder)
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
        text = map_files.map_yaml(dict(description, image=name + ".pgm")).encode()
        with _opened_folder(self.folder, "write to") as folder:
            _create_in(folder, name + ".yaml", lambda stream: stream.write(text))


# --- previews ---------------------------------------------------------------------------

def preview_pixels(occupancy_map, scale=1):
    """Grey levels as map_saver draws them (free white, occupied black, unknown grey), top row = highest y.
    Refused, before any work, when the preview would have more than MAX_PREVIEW_PIXELS pixels."""
    if scale < 1:
        raise MapStoreError("--scale must be 1 or more")
    if occupancy_map.width * occupancy_map.height * scale * scale > MAX_PREVIEW_PIXELS:
        largest = int((MAX_PREVIEW_PIXELS / (occupancy_map.width * occupancy_map.height)) ** 0.5)
        raise MapStoreError(f"--scale {scale} would make a preview of {occupancy_map.width * scale} x"
                            f" {occupancy_map.height * scale} pixels, over the limit of {MAX_PREVIEW_PIXELS};"
                            f" this map allows --scale {largest} at most")
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


def _modified(*paths):
    """The modification time of the first of `paths` that exists (0 if none does: removed meanwhile)."""
    for path in paths:
        try:
            return os.lstat(path).st_mtime
        except OSError:
            continue
    return 0.0


def _is_regular_file(path):
    """A regular file itself, not a link to one."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _split_source(source):
    """The folder to import from and the YAML's name in it (None: the folder's one YAML)."""
    if os.path.isdir(source):
        return source, None
    if not os.path.lexists(source):
        raise MapStoreError(f"{source}: no such file or folder")
    if not source.endswith(".yaml"):
        raise MapStoreError(f"{source}: give the map's YAML file (NAME.yaml) or a folder holding one")
    return os.path.dirname(source) or ".", os.path.basename(source)


def _the_yaml_in(folder_descriptor, folder):
    found = sorted(entry for entry in os.listdir(folder_descriptor)
                   if entry.endswith(".yaml") and not entry.startswith(".") and entry != CURRENT + ".yaml")
    if len(found) != 1:
        raise MapStoreError(f"{folder} holds {len(found)} map YAML files ({', '.join(found) or 'none'});"
                            " give the map's YAML file instead")
    return found[0]


def _checked_import(origin, folder, yaml_entry):
    """The description and the image file of the map to import, both checked: the YAML map_server's,
    its image a plain file name beside it, a PGM within the limits that makes a map. Messages name
    the files the owner gave, never a staging copy."""
    yaml_path = os.path.join(folder, yaml_entry)
    content = _read_in(origin, yaml_entry, yaml_path, map_files.MAX_YAML_BYTES, "map file")
    description = map_files.parse_map_description(content, yaml_path)
    image = description["image"]
    if os.path.isabs(image):
        raise MapStoreError(f"{yaml_path}: image {map_files.shown(image)} is an absolute path; an imported"
                            " map's image must be a file name beside its YAML")
    if not _plain_file_name(image):
        raise MapStoreError(f"{yaml_path}: image {map_files.shown(image)} is not a plain file name beside its"
                            " YAML (no folders, no '..')")
    image_path = os.path.join(folder, image)
    image_file = _read_in(origin, image, image_path, map_files.MAX_IMAGE_BYTES, f"{yaml_path}: its image {image}")
    if image_file[:2] not in PGM_MAGICS:
        raise MapStoreError(f"{image_path} is not a PGM image (P5 or P2); it starts with {image_file[:2]!r}")
    try:
        map_files.occupancy_map_of(description, map_files.parse_pnm(image_file, image_path))
    except map_files.MapFileError as error:
        raise MapStoreError(f"{yaml_path} is not a usable map: {error}") from None
    return description, image_file


@contextlib.contextmanager
def _opened_folder(folder, doing):
    """A descriptor of `folder`, opened once: every file of an import or export is reached through it."""
    try:
        descriptor = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as error:
        raise MapStoreError(f"cannot {doing} {folder}: {error.strerror}") from None
    try:
        yield descriptor
    finally:
        os.close(descriptor)


def _exists_in(folder_descriptor, entry):
    try:
        os.stat(entry, dir_fd=folder_descriptor, follow_symlinks=False)
    except FileNotFoundError:
        return False
    return True


def _open_in(folder_descriptor, entry, path, what):
    """`entry` of the folder opened for reading, refused when it is a link or no regular file."""
    try:
        descriptor = os.open(entry, READ_FLAGS, dir_fd=folder_descriptor)
    except FileNotFoundError:
        raise MapStoreError(f"{what} ({path}) does not exist") from None
    except OSError as error:
        if error.errno == errno.ELOOP:
            raise MapStoreError(f"{what} ({path}) is a link, not a regular file (links are refused)") from None
        raise MapStoreError(f"{what} ({path}) cannot be read: {error.strerror}") from None
    stream = os.fdopen(descriptor, "rb")
    if not stat.S_ISREG(os.fstat(descriptor).st_mode):
        stream.close()
        raise MapStoreError(f"{what} ({path}) is not a regular file (links and devices are refused)")
    return stream


def _read_in(folder_descriptor, entry, path, limit, what):
    with _open_in(folder_descriptor, entry, path, what) as stream:
        try:
            return map_files.read_stream_bounded(stream, path, limit, what)
        except map_files.MapFileError as error:
            raise MapStoreError(str(error)) from None


def _copy_bag(folder_descriptor, entry, path, staged):
    """Copy the session bag beside an imported map, its header checked first and its size bounded."""
    with _open_in(folder_descriptor, entry, path, "the session bag") as stream:
        size = os.fstat(stream.fileno()).st_size
        if size > MAX_BAG_BYTES:
            raise MapStoreError(f"the session bag {path} has {size} bytes, over the limit of {MAX_BAG_BYTES}")
        if stream.read(len(BAG_MAGIC)) != BAG_MAGIC:
            raise MapStoreError(f"{path} is not a ROS 1 bag (no '#ROSBAG V2.0' header)")
        stream.seek(0)
        with open(staged, "xb") as copy:
            if _copy_stream(stream, copy, MAX_BAG_BYTES) > MAX_BAG_BYTES:
                raise MapStoreError(f"the session bag {path} grew over the limit of {MAX_BAG_BYTES} bytes while read")
            _flush(copy)


def _copy_stream(source, target, limit):
    """Copy until the end or just past `limit` bytes; returns how many were copied."""
    copied = 0
    while copied <= limit:
        chunk = source.read(COPY_CHUNK)
        if not chunk:
            break
        target.write(chunk)
        copied += len(chunk)
    return copied


def _write_staged(staging, entry, content):
    path = os.path.join(staging, entry)
    with open(path, "xb") as stream:
        stream.write(content)
        _flush(stream)
    return path


def _create_in(folder_descriptor, entry, write):
    """Create `entry` in the folder with what `write(stream)` writes, whole or not at all: written to a new
    file of a random hidden name, then linked to `entry`, which must not exist. Returns `entry`."""
    temporary = f".{entry}.{secrets.token_hex(8)}.part"
    descriptor = os.open(temporary, CREATE_FLAGS, 0o644, dir_fd=folder_descriptor)
    try:
        with os.fdopen(descriptor, "wb") as stream:
            os.fchmod(stream.fileno(), 0o644)
            write(stream)
            _flush(stream)
        try:
            # Never through a link: if someone swapped the temporary for one, link(2) links the link.
            os.link(temporary, entry, src_dir_fd=folder_descriptor, dst_dir_fd=folder_descriptor,
                    follow_symlinks=False)
        except FileExistsError:
            raise MapStoreError(f"{entry} already exists; nothing was replaced") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(temporary, dir_fd=folder_descriptor)
    return entry


def _copy_into(folder_descriptor, entry, source):
    """Copy `source` (a file of the map folder) to `entry` of the folder, keeping its date."""
    with open(source, "rb") as stream:
        times = os.fstat(stream.fileno())

        def write(target):
            shutil.copyfileobj(stream, target, COPY_CHUNK)
            target.flush()
            os.utime(target.fileno(), ns=(times.st_atime_ns, times.st_mtime_ns))
        return _create_in(folder_descriptor, entry, write)


def _flush(stream):
    stream.flush()
    os.fsync(stream.fileno())


def _link_new(source, target):
    """Give `source` the name `target` too, failing if `target` exists (link(2) never replaces)."""
    try:
        os.link(source, target, follow_symlinks=False)
    except FileExistsError:
        raise MapStoreError(f"{target} already exists; nothing was replaced") from None
    except FileNotFoundError:
        raise MapStoreError(f"{source} does not exist") from None


def _unlink_all(paths):
    for path in reversed(paths):
        with contextlib.suppress(OSError):
            os.unlink(path)


def _sync_folder(folder):
    descriptor = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
