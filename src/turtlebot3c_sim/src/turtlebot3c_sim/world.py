"""2D worlds for the simulator: obstacles, ray casting, collision and rasterisation.

A world is a set of solid obstacles seen at laser height: circles and solids
bounded by closed polygon rings (a solid with two rings, e.g. the hexagonal
wall of turtlebot3_world, is the area between them: even-odd rule). World
files are YAML, looked up by name in the `worlds/` folder of this package:

    name: example
    spawn: [x, y, yaw]               # default start pose
    bounds: [xmin, ymin, xmax, ymax] # optional; else the obstacles' extent + 0.5 m
    obstacles:
      - {type: circle, center: [x, y], radius: r}
      - {type: polygon, points: [[x, y], ...]}                  # filled polygon
      - {type: regular_polygon, center: [x, y], sides: 6, circumradius: r, rotation: 0.0}
      - {type: ring, outer: <polygon or regular_polygon>, inner: <same>}  # area between
      - {type: wall, from: [x, y], to: [x, y], thickness: 0.1}  # a thick segment
      - {type: box, center: [x, y], size: [sx, sy], rotation: 0.0}

Ray casting is vectorised over all rays and all obstacle edges at once.
"""
import math
import os
from pathlib import Path
from typing import List, Sequence, Tuple

import numpy as np
import yaml

_PACKAGE = "turtlebot3c_sim"
WORLD_NAMES = ("turtlebot3_world", "empty", "house")


class WorldError(ValueError):
    """A world file that cannot be found or does not describe a valid world."""


class World:
    """Obstacles of one world; all coordinates in metres in the world frame."""

    def __init__(self, name: str, rings: Sequence[Sequence[np.ndarray]], circles: Sequence[Tuple[float, float, float]],
                 spawn_pose: Tuple[float, float, float], bounds=None):
        self.name = name
        # Each solid is a list of closed rings (K, 2); even-odd rule inside a solid.
        self.solids: List[List[np.ndarray]] = [[np.asarray(ring, float) for ring in solid] for solid in rings]
        circle_array = np.asarray(circles, float).reshape(-1, 3)
        self.circle_centers = circle_array[:, :2].copy()
        self.circle_radii = circle_array[:, 2].copy()
        starts, ends = [], []
        for solid in self.solids:
            for ring in solid:
                starts.append(ring)
                ends.append(np.roll(ring, -1, axis=0))
        self.segment_starts = np.concatenate(starts) if starts else np.zeros((0, 2))
        self.segment_ends = np.concatenate(ends) if ends else np.zeros((0, 2))
        self._segment_vectors = self.segment_ends - self.segment_starts
        self._segment_lengths_squared = np.maximum((self._segment_vectors ** 2).sum(axis=1), 1e-300)
        self._segment_lo = np.minimum(self.segment_starts, self.segment_ends)
        self._segment_hi = np.maximum(self.segment_starts, self.segment_ends)
        self.spawn_pose = tuple(float(value) for value in spawn_pose)
        self.bounds = tuple(float(value) for value in bounds) if bounds is not None else self._extent(0.5)

    def _extent(self, margin):
        points = [self.segment_starts]
        if len(self.circle_radii):
            radii = self.circle_radii[:, None]
            points += [self.circle_centers - radii, self.circle_centers + radii]
        points = np.concatenate(points) if points else np.zeros((0, 2))
        if len(points) == 0:
            raise WorldError(f"world {self.name!r} has no obstacles: give it 'bounds'")
        lo, hi = points.min(axis=0) - margin, points.max(axis=0) + margin
        return (lo[0], lo[1], hi[0], hi[1])

    # --- ray casting ---------------------------------------------------------------

    def raycast(self, x: float, y: float, angles, max_range: float) -> np.ndarray:
        """Distance from (x, y) to the first obstacle along each absolute angle (rad).

        np.inf where nothing is hit within max_range. The result has the shape of `angles`.
        """
        angles = np.asarray(angles, float)
        dx, dy = np.cos(angles.ravel()), np.sin(angles.ravel())
        best = np.full(dx.shape, np.inf)
        self._cast_segments(x, y, dx, dy, max_range, best)
        self._cast_circles(x, y, dx, dy, max_range, best)
        best[best > max_range] = np.inf
        return best.reshape(angles.shape)

    def _cast_segments(self, x, y, dx, dy, max_range, best):
        near = self._segments_near(x, y, max_range)
        if not near.any():
            return
        ax = self.segment_starts[near, 0] - x
        ay = self.segment_starts[near, 1] - y
        ex = self.segment_ends[near, 0] - self.segment_starts[near, 0]
        ey = self.segment_ends[near, 1] - self.segment_starts[near, 1]
        # o + t*d = a + u*e  =>  t = (a x e) / (d x e),  u = (a x d) / (d x e)
        denominator = dx[:, None] * ey[None, :] - dy[:, None] * ex[None, :]
        t_numerator = (ax * ey - ay * ex)[None, :]
        u_numerator = ax[None, :] * dy[:, None] - ay[None, :] * dx[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = t_numerator / denominator
            u = u_numerator / denominator
        hit = (denominator != 0) & (t >= 0) & (u >= 0) & (u <= 1)
        np.minimum(best, np.where(hit, t, np.inf).min(axis=1), out=best)

    def _segments_near(self, x, y, max_range):
        """Segments whose bounding box comes within max_range of (x, y): a cheap cull."""
        return ((self._segment_lo[:, 0] <= x + max_range) & (self._segment_hi[:, 0] >= x - max_range)
                & (self._segment_lo[:, 1] <= y + max_range) & (self._segment_hi[:, 1] >= y - max_range))

    def _cast_circles(self, x, y, dx, dy, max_range, best):
        if not len(self.circle_radii):
            return
        cx = self.circle_centers[:, 0] - x
        cy = self.circle_centers[:, 1] - y
        c = cx * cx + cy * cy - self.circle_radii ** 2
        b = dx[:, None] * cx[None, :] + dy[:, None] * cy[None, :]
        discriminant = b * b - c[None, :]
        root = np.sqrt(np.maximum(discriminant, 0.0))
        # From outside a circle the near intersection counts; from inside, the far one.
        t = np.where(c[None, :] > 0, b - root, b + root)
        hit = (discriminant >= 0) & (t >= 0)
        np.minimum(best, np.where(hit, t, np.inf).min(axis=1), out=best)

    # --- occupancy -----------------------------------------------------------------

    def contains(self, points) -> np.ndarray:
        """Whether each point (..., 2) lies inside an obstacle."""
        points = np.asarray(points, float)
        flat = points.reshape(-1, 2)
        inside = np.zeros(len(flat), bool)
        for solid in self.solids:
            inside |= _inside_rings(flat, solid)
        for (cx, cy), radius in zip(self.circle_centers, self.circle_radii):
            inside |= (flat[:, 0] - cx) ** 2 + (flat[:, 1] - cy) ** 2 <= radius * radius
        return inside.reshape(points.shape[:-1])

    def distance_to_boundary(self, points) -> np.ndarray:
        """Distance from each point (..., 2) to the nearest obstacle boundary."""
        points = np.asarray(points, float)
        flat = points.reshape(-1, 2)
        best = np.full(len(flat), np.inf)
        for start, end in zip(self.segment_starts, self.segment_ends):
            np.minimum(best, _distance_to_segment(flat, start, end), out=best)
        for center, radius in zip(self.circle_centers, self.circle_radii):
            np.minimum(best, np.abs(np.hypot(flat[:, 0] - center[0], flat[:, 1] - center[1]) - radius), out=best)
        return best.reshape(points.shape[:-1])

    def clearance(self, x: float, y: float) -> float:
        """Distance from (x, y) to the nearest obstacle boundary (np.inf in an empty world)."""
        best = np.inf
        if len(self.segment_starts):
            rel = np.array([x, y]) - self.segment_starts
            along = np.clip((rel * self._segment_vectors).sum(axis=1) / self._segment_lengths_squared, 0.0, 1.0)
            gap = rel - along[:, None] * self._segment_vectors
            best = math.sqrt(float((gap * gap).sum(axis=1).min()))
        if len(self.circle_radii):
            circles = np.hypot(self.circle_centers[:, 0] - x, self.circle_centers[:, 1] - y) - self.circle_radii
            best = min(best, float(np.abs(circles).min()))
        return best

    def collides(self, x: float, y: float, radius: float) -> bool:
        """Whether a disc of `radius` centred on (x, y) overlaps an obstacle."""
        point = np.array([[x, y]])
        if self.contains(point)[0]:
            return True
        near = self._segments_near(x, y, radius)
        for start, end in zip(self.segment_starts[near], self.segment_ends[near]):
            if _distance_to_segment(point, start, end)[0] < radius:
                return True
        if len(self.circle_radii):
            gaps = np.hypot(self.circle_centers[:, 0] - x, self.circle_centers[:, 1] - y) - self.circle_radii
            return bool((gaps < radius).any())
        return False

    def polygon_collides(self, polygon) -> bool:
        """Whether a closed polygon (K, 2), e.g. a robot footprint in the world frame, overlaps an obstacle."""
        polygon = np.asarray(polygon, float)
        lo, hi = polygon.min(axis=0), polygon.max(axis=0)
        near = ((self._segment_lo[:, 0] <= hi[0]) & (self._segment_hi[:, 0] >= lo[0])
                & (self._segment_lo[:, 1] <= hi[1]) & (self._segment_hi[:, 1] >= lo[1]))
        if near.any() and _edges_cross(polygon, self.segment_starts[near], self.segment_ends[near]):
            return True
        if self.contains(polygon[:1])[0]:
            return True  # wholly inside an obstacle
        if near.any() and _inside_rings(self.segment_starts[near], [polygon]).any():
            return True  # an obstacle wholly inside the polygon
        if len(self.circle_radii):
            centers_inside = _inside_rings(self.circle_centers, [polygon])
            gaps = np.full(len(self.circle_radii), np.inf)
            for start, end in zip(polygon, np.roll(polygon, -1, axis=0)):
                np.minimum(gaps, _distance_to_segment(self.circle_centers, start, end), out=gaps)
            if (centers_inside | (gaps < self.circle_radii)).any():
                return True
        return False

    def polygon_boundary_touches(self, polygon) -> bool:
        """Whether the edges of a closed polygon (K, 2) cross or touch an obstacle's boundary.

        Enough for a robot moving in small steps from a free pose (nothing can get wholly
        inside or around it without crossing an edge first), and much cheaper than
        `polygon_collides`.
        """
        polygon = np.asarray(polygon, float)
        lo, hi = polygon.min(axis=0), polygon.max(axis=0)
        p0 = polygon
        edges = np.concatenate((polygon[1:], polygon[:1])) - p0
        near = ((self._segment_lo[:, 0] <= hi[0]) & (self._segment_hi[:, 0] >= lo[0])
                & (self._segment_lo[:, 1] <= hi[1]) & (self._segment_hi[:, 1] >= lo[1]))
        if near.any():
            q0 = self.segment_starts[near]
            e = self.segment_ends[near] - q0
            rx = q0[None, :, 0] - p0[:, None, 0]
            ry = q0[None, :, 1] - p0[:, None, 1]
            dx, dy = edges[:, None, 0], edges[:, None, 1]
            denominator = dx * e[None, :, 1] - dy * e[None, :, 0]
            t = rx * e[None, :, 1] - ry * e[None, :, 0]  # times denominator
            u = rx * dy - ry * dx
            size = np.abs(denominator)
            sign = np.sign(denominator)
            t, u = t * sign, u * sign
            if ((size > 0) & (t >= 0) & (t <= size) & (u >= 0) & (u <= size)).any():
                return True
        if len(self.circle_radii):
            r = self.circle_radii
            close = ((self.circle_centers[:, 0] + r >= lo[0]) & (self.circle_centers[:, 0] - r <= hi[0])
                     & (self.circle_centers[:, 1] + r >= lo[1]) & (self.circle_centers[:, 1] - r <= hi[1]))
            if close.any():
                centers, radii = self.circle_centers[close], r[close]
                rel = centers[None, :, :] - p0[:, None, :]
                lengths = (edges * edges).sum(axis=1)[:, None]
                along = np.clip((rel * edges[:, None, :]).sum(axis=2) / lengths, 0.0, 1.0)
                gap = rel - along[:, :, None] * edges[:, None, :]
                if ((gap * gap).sum(axis=2) <= radii[None, :] ** 2).any():
                    return True
        return False

    def polygon_clearance(self, polygon, margin: float) -> float:
        """Distance between the boundary of a closed polygon (K, 2) and the nearest obstacle, capped at
        `margin`; 0 when they touch or cross. Like `polygon_boundary_touches`, it looks at boundaries only.
        """
        polygon = np.asarray(polygon, float)
        lo, hi = polygon.min(axis=0) - margin, polygon.max(axis=0) + margin
        edges = np.concatenate((polygon[1:], polygon[:1])) - polygon
        edge_lengths = (edges * edges).sum(axis=1)
        best = margin
        near = ((self._segment_lo[:, 0] <= hi[0]) & (self._segment_hi[:, 0] >= lo[0])
                & (self._segment_lo[:, 1] <= hi[1]) & (self._segment_hi[:, 1] >= lo[1]))
        if near.any():
            if self.polygon_boundary_touches(polygon):
                return 0.0
            starts, vectors = self.segment_starts[near], self._segment_vectors[near]
            # Polygon corners to obstacle segments, obstacle segment ends to polygon edges.
            best = min(best, _point_segment_distances(polygon, starts, vectors, self._segment_lengths_squared[near]))
            ends = np.concatenate((starts, self.segment_ends[near]))
            best = min(best, _point_segment_distances(ends, polygon, edges, edge_lengths))
        if len(self.circle_radii):
            r = self.circle_radii
            close = ((self.circle_centers[:, 0] + r >= lo[0]) & (self.circle_centers[:, 0] - r <= hi[0])
                     & (self.circle_centers[:, 1] + r >= lo[1]) & (self.circle_centers[:, 1] - r <= hi[1]))
            if close.any():
                rel = self.circle_centers[close][:, None, :] - polygon[None, :, :]
                along = np.clip((rel * edges[None, :, :]).sum(axis=2) / edge_lengths[None, :], 0.0, 1.0)
                gap = rel - along[:, :, None] * edges[None, :, :]
                distances = np.sqrt((gap * gap).sum(axis=2).min(axis=1)) - r[close]
                best = min(best, float(distances.min()))
        return max(0.0, best)

    def rasterize(self, resolution: float, origin_xy, width: int, height: int) -> np.ndarray:
        """Occupied cells of a grid (height, width); row = y index, column = x index.

        A cell is occupied when its centre is inside an obstacle or within half a cell
        of an obstacle's boundary (so thin walls and edges are never lost).
        """
        xs = origin_xy[0] + (np.arange(width) + 0.5) * resolution
        ys = origin_xy[1] + (np.arange(height) + 0.5) * resolution
        grid = np.stack(np.meshgrid(xs, ys), axis=-1)
        return self.contains(grid) | (self.distance_to_boundary(grid) <= resolution / 2.0)


def _inside_rings(points, rings) -> np.ndarray:
    """Even-odd point-in-polygon test of points (N, 2) against a set of rings."""
    inside = np.zeros(len(points), bool)
    px, py = points[:, 0], points[:, 1]
    for ring in rings:
        ring = np.asarray(ring, float)
        for (x0, y0), (x1, y1) in zip(ring, np.roll(ring, -1, axis=0)):
            straddles = (y0 > py) != (y1 > py)
            with np.errstate(divide="ignore", invalid="ignore"):
                crossing_x = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
            inside ^= straddles & (px < crossing_x)
    return inside


def _point_segment_distances(points, starts, vectors, lengths_squared) -> float:
    """Smallest distance from any of the points (N, 2) to any of the segments (starts, vectors: (K, 2))."""
    rel = points[:, None, :] - starts[None, :, :]
    along = np.clip((rel * vectors[None, :, :]).sum(axis=2) / lengths_squared[None, :], 0.0, 1.0)
    gap = rel - along[:, :, None] * vectors[None, :, :]
    return math.sqrt(float((gap * gap).sum(axis=2).min()))


def _distance_to_segment(points, start, end) -> np.ndarray:
    edge = end - start
    length_squared = float(edge @ edge)
    relative = points - start
    if length_squared == 0.0:
        return np.hypot(relative[:, 0], relative[:, 1])
    along = np.clip((relative @ edge) / length_squared, 0.0, 1.0)
    closest = relative - along[:, None] * edge
    return np.hypot(closest[:, 0], closest[:, 1])


def _edges_cross(polygon, starts, ends) -> bool:
    """Whether any edge of a closed polygon intersects any of the segments (starts[i], ends[i])."""
    p0 = polygon[:, None, :]
    p1 = np.roll(polygon, -1, axis=0)[:, None, :]
    q0, q1 = starts[None, :, :], ends[None, :, :]

    def orientation(a, b, c):
        return (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (b[..., 1] - a[..., 1]) * (c[..., 0] - a[..., 0])
    d1, d2 = orientation(q0, q1, p0), orientation(q0, q1, p1)
    d3, d4 = orientation(p0, p1, q0), orientation(p0, p1, q1)
    return bool((((d1 > 0) != (d2 > 0)) & ((d3 > 0) != (d4 > 0)) & (d1 != d2) & (d3 != d4)).any())


# --- world files ------------------------------------------------------------------------

def world_search_path() -> List[Path]:
    """Folders searched for `<name>.yaml`: $TURTLEBOT3C_SIM_WORLDS, the install and source trees."""
    folders = [Path(entry) for entry in os.environ.get("TURTLEBOT3C_SIM_WORLDS", "").split(os.pathsep) if entry]
    for prefix in os.environ.get("CMAKE_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            folders.append(Path(prefix) / "share" / _PACKAGE / "worlds")
    here = Path(__file__).resolve().parent
    folders.append(here.parents[1] / "worlds")  # source tree: src/turtlebot3c_sim/worlds
    if len(here.parents) > 3:
        folders.append(here.parents[3] / "share" / _PACKAGE / "worlds")  # <prefix>/lib/python3/dist-packages
    return folders


def find_world_file(name_or_path: str) -> Path:
    candidate = Path(name_or_path)
    if candidate.suffix in (".yaml", ".yml") or os.sep in name_or_path:
        if candidate.is_file():
            return candidate
        raise WorldError(f"world file {name_or_path} does not exist")
    folders = world_search_path()
    for folder in folders:
        path = folder / f"{name_or_path}.yaml"
        if path.is_file():
            return path
    known = sorted({path.stem for folder in folders if folder.is_dir() for path in folder.glob("*.yaml")})
    raise WorldError(f"unknown world {name_or_path!r}; known worlds: {', '.join(known) or 'none found'}")


def load_world(name_or_path: str) -> World:
    """The world called `name_or_path` (e.g. "turtlebot3_world", "empty", "house") or read from a YAML file."""
    path = find_world_file(name_or_path)
    try:
        description = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise WorldError(f"{path}: not valid YAML: {error}") from None
    try:
        return world_from_description(description, default_name=path.stem)
    except WorldError as error:
        raise WorldError(f"{path}: {error}") from None


def world_from_description(description, default_name="world") -> World:
    if not isinstance(description, dict):
        raise WorldError("a world file must be a mapping with 'obstacles'")
    solids, circles = [], []
    for index, obstacle in enumerate(description.get("obstacles") or []):
        try:
            _add_obstacle(obstacle, solids, circles)
        except (KeyError, TypeError, ValueError) as error:
            raise WorldError(f"obstacle {index} ({obstacle!r}) is invalid: {error!s}") from None
    spawn = description.get("spawn", [0.0, 0.0, 0.0])
    if len(spawn) != 3:
        raise WorldError("'spawn' must be [x, y, yaw]")
    bounds = description.get("bounds")
    if bounds is not None and len(bounds) != 4:
        raise WorldError("'bounds' must be [xmin, ymin, xmax, ymax]")
    return World(str(description.get("name", default_name)), solids, circles, spawn, bounds)


def _add_obstacle(obstacle, solids, circles):
    kind = obstacle["type"]
    if kind == "circle":
        radius = float(obstacle["radius"])
        if radius <= 0:
            raise ValueError("radius must be positive")
        circles.append((float(obstacle["center"][0]), float(obstacle["center"][1]), radius))
    elif kind == "ring":
        solids.append([_polygon(obstacle["outer"]), _polygon(obstacle["inner"])])
    else:
        solids.append([_polygon(obstacle)])


def _polygon(shape) -> np.ndarray:
    kind = shape["type"]
    if kind == "polygon":
        points = np.asarray(shape["points"], float)
    elif kind == "regular_polygon":
        sides = int(shape["sides"])
        angles = float(shape.get("rotation", 0.0)) + 2.0 * math.pi * np.arange(sides) / sides
        radius = float(shape["circumradius"])
        points = np.stack([np.cos(angles), np.sin(angles)], axis=1) * radius + np.asarray(shape["center"], float)
    elif kind == "box":
        sx, sy = (float(value) / 2.0 for value in shape["size"])
        points = _place(np.array([[-sx, -sy], [sx, -sy], [sx, sy], [-sx, sy]]),
                        shape["center"], float(shape.get("rotation", 0.0)))
    elif kind == "wall":
        start, end = np.asarray(shape["from"], float), np.asarray(shape["to"], float)
        half = float(shape.get("thickness", 0.1)) / 2.0
        direction = end - start
        length = float(np.hypot(*direction))
        if length == 0.0:
            raise ValueError("a wall needs two distinct ends")
        normal = np.array([-direction[1], direction[0]]) / length * half
        along = direction / length * half  # square ends that close corners between walls
        points = np.array([start - along - normal, end + along - normal, end + along + normal, start - along + normal])
    else:
        raise ValueError(f"unknown type {kind!r} (circle, polygon, regular_polygon, box, wall, ring)")
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 3:
        raise ValueError("a polygon needs at least three [x, y] points")
    return points


def _place(points, center, rotation):
    c, s = math.cos(rotation), math.sin(rotation)
    return points @ np.array([[c, s], [-s, c]]) + np.asarray(center, float)
