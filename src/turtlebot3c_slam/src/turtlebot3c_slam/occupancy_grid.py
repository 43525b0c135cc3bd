"""A growable log-odds occupancy grid and the cell updates a scan makes. Pure numpy; no rospy.

Cells live on a fixed lattice: cell (i, j) covers x in [(i - s) r, (i + 1 - s) r), y in
[(j - s) r, (j + 1 - s) r) for resolution r and cell shift s (0: cell corners at the map
frame's origin; 1/2: a cell centred there), whatever part of the lattice the array
currently holds, so updates computed once stay valid when the grid grows. Updates are
additive (log-odds and an observation count), so a scan's update can be taken back
exactly by applying it with sign -1: a rolling local map adds its newest scan and
removes its oldest.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import transform_points
from turtlebot3c_maps.map_files import OccupancyMap

LATTICE_SPAN = 1 << 21  # cell indices are kept within +-2^20 (52 km at 5 cm)


class CellUpdate:
    """The cells one scan observed: lattice indices of free cells and of hit cells (unique).

    For hit cells it also carries where in the cell the hits were (sum of their positions
    within the cell, in cells, and their count), so the map knows obstacles to sub-cell
    precision.
    """

    def __init__(self, free, hits, hit_sums=None, hit_counts=None):
        self.free = free  # (F, 2) int64 (i, j)
        self.hits = hits  # (H, 2) int64
        self.hit_sums = np.full((len(hits), 2), 0.5) if hit_sums is None else hit_sums  # (H, 2)
        self.hit_counts = np.ones(len(hits)) if hit_counts is None else hit_counts     # (H,)
        self._bounds = _bounds(free, hits)

    def bounds(self):
        """(lowest, highest) lattice cell it touches; None when it touches none."""
        return self._bounds


def _bounds(*cell_sets):
    """(lowest, highest) (i, j) over cell arrays (N, 2), None when all are empty; kept per update, for
    an update is applied to the local map at least twice (added, taken back)."""
    present = [cells for cells in cell_sets if len(cells)]
    if not present:
        return None
    return np.min([cells.min(axis=0) for cells in present], axis=0), \
        np.max([cells.max(axis=0) for cells in present], axis=0)


def _cell_keys(cells):
    return (cells[:, 0] + LATTICE_SPAN // 2) * LATTICE_SPAN + (cells[:, 1] + LATTICE_SPAN // 2)


def _cells_of_keys(keys):
    return np.column_stack((keys // LATTICE_SPAN - LATTICE_SPAN // 2, keys % LATTICE_SPAN - LATTICE_SPAN // 2))


def hit_cells(points, resolution, cell_shift=0.0):
    """CellUpdate-style hits of points (N, 2) in the map frame: cells, position sums within them, counts."""
    scaled = points / resolution + cell_shift
    cells = np.floor(scaled).astype(np.int64)
    if len(cells) == 0:
        return cells.reshape(0, 2), np.zeros((0, 2)), np.zeros(0)
    keys, inverse = np.unique(_cell_keys(cells), return_inverse=True)
    fraction = scaled - cells
    sums = np.column_stack((np.bincount(inverse, fraction[:, 0], len(keys)),
                            np.bincount(inverse, fraction[:, 1], len(keys))))
    return _cells_of_keys(keys), sums, np.bincount(inverse, minlength=len(keys)).astype(np.float64)


def trace_scan(rays, pose, resolution, cell_shift=0.0, walls=None):
    """The CellUpdate of a scan (ScanRays in the robot frame) taken at `pose` in the map frame.

    Rays are sampled every half cell, so no crossed cell is skipped; cells holding an
    endpoint of a hit are hits, never free. A ray that ends at no hit (no return, or a hit
    beyond the usable range) stops before the first cell `walls` (cells (N, 2) -> bool, e.g.
    LogOddsGrid.occupied) calls a wall: glass, a black wall or a sensor that missed its echo
    say nothing about what lies behind a wall that other scans saw.
    """
    origin = transform_points(pose, rays.origin)[0]
    hits = transform_points(pose, rays.hits)
    ends = np.concatenate((hits, transform_points(pose, rays.free_ends)))
    hit_cells_, hit_sums, hit_counts = hit_cells(hits, resolution, cell_shift)
    if len(ends) == 0:
        return CellUpdate(np.empty((0, 2), np.int64), hit_cells_, hit_sums, hit_counts)
    step = resolution * 0.5
    reach = ends - origin
    samples = np.maximum(np.ceil(np.hypot(reach[:, 0], reach[:, 1]) / step).astype(np.int64), 1)
    starts = np.cumsum(samples) - samples
    ray = np.repeat(np.arange(len(ends)), samples)  # the ray of each sample
    fraction = np.arange(len(ray)) - starts[ray]
    fraction = fraction / samples[ray]
    cols = _sampled_cells(origin[0], reach[ray, 0], fraction, resolution, cell_shift)
    rows = _sampled_cells(origin[1], reach[ray, 1], fraction, resolution, cell_shift)
    if walls is not None and len(rays.free_ends):
        before = _before_walls(cols, rows, starts[len(hits)], starts, ray, walls)
        cols, rows = cols[before], rows[before]
    free_cells = _crossed_cells(cols, rows, hit_cells_) if len(cols) else np.empty((0, 2), np.int64)
    return CellUpdate(free_cells, hit_cells_, hit_sums, hit_counts)


def _sampled_cells(start, reach, fraction, resolution, cell_shift):
    """Lattice indices along one axis of the points start + reach * fraction (in place: a scan
    samples ~10^5 points, and each pass over them counts)."""
    values = reach * fraction
    values += start
    values /= resolution
    values += cell_shift
    return np.floor(values, out=values).astype(np.int64)


def _before_walls(cols, rows, first_checked, starts, ray, walls):
    """Which samples (cells along rays, each ray's from its origin out; `ray` numbers their rays)
    lie before the first sample of their ray that is a wall; only samples from `first_checked` on
    can be walls."""
    wall = np.zeros(len(cols), dtype=bool)
    wall[first_checked:] = walls(np.column_stack((cols[first_checked:], rows[first_checked:])))
    walls_so_far = np.cumsum(wall)
    walls_before_ray = (walls_so_far - wall)[starts]
    return walls_so_far == walls_before_ray[ray]


def _crossed_cells(cols, rows, hits):
    """The distinct cells among (cols, rows), less `hits`: marked in a mask over their bounding
    box, which is linear in the samples where sorting them is not (a scan samples ~10^5)."""
    low = np.array([cols.min(), rows.min()])
    width, height = cols.max() - low[0] + 1, rows.max() - low[1] + 1
    crossed = np.zeros(width * height, dtype=bool)
    crossed[(rows - low[1]) * width + (cols - low[0])] = True
    if len(hits):
        inside = hits - low
        inside = inside[(inside >= 0).all(axis=1) & (inside[:, 0] < width) & (inside[:, 1] < height)]
        crossed[inside[:, 1] * width + inside[:, 0]] = False
    flat = np.flatnonzero(crossed)
    return np.column_stack((flat % width + low[0], flat // width + low[1]))


class LogOddsGrid:
    """Occupancy as log-odds per cell, with a count of observations (0 = unknown)."""

    GROWTH = 64  # cells added beyond what is needed, so the array is rarely reallocated

    def __init__(self, resolution, hit_log_odds=0.85, free_log_odds=-0.4, cell_shift=0.0):
        self.resolution = float(resolution)
        self.cell_shift = float(cell_shift)
        self.hit_log_odds = float(hit_log_odds)
        self.free_log_odds = float(free_log_odds)
        self.offset = np.zeros(2, dtype=np.int64)   # lattice (i, j) of array cell [0, 0]
        self.log_odds = np.zeros((0, 0), dtype=np.float32)  # [j - offset_j, i - offset_i]
        self.observations = np.zeros((0, 0), dtype=np.int32)
        self.hit_sums = np.zeros((0, 0, 2), dtype=np.float32)  # positions of hits within their cell
        self.hit_counts = np.zeros((0, 0), dtype=np.float32)

    @property
    def shape(self):
        return self.log_odds.shape

    def reserve(self, low, high):
        """Grow the arrays so lattice cells low..high (inclusive, (i, j)) are inside."""
        height, width = self.log_odds.shape
        if width and (low >= self.offset).all() and (high < self.offset + (width, height)).all():
            return
        if width:
            old_low, old_high = self.offset, self.offset + (width, height) - 1
            new_low = np.where(low < old_low, low - self.GROWTH, old_low)
            new_high = np.where(high > old_high, high + self.GROWTH, old_high)
        else:
            new_low, new_high = low - self.GROWTH, high + self.GROWTH
        size = new_high - new_low + 1
        grown = []
        for array in (self.log_odds, self.observations, self.hit_sums, self.hit_counts):
            bigger = np.zeros((size[1], size[0]) + array.shape[2:], dtype=array.dtype)
            if width:
                di, dj = self.offset - new_low
                bigger[dj:dj + height, di:di + width] = array
            grown.append(bigger)
        self.log_odds, self.observations, self.hit_sums, self.hit_counts = grown
        self.offset = new_low

    def add_scan(self, rays, pose):
        """Mark a scan (ScanRays in the robot frame) taken at `pose` in the map frame."""
        self.apply(self.trace(rays, pose))

    def trace(self, rays, pose):
        """The scan's CellUpdate on this grid: rays without a hit stop at the walls it holds."""
        return trace_scan(rays, pose, self.resolution, self.cell_shift, walls=self.occupied)

    def hits_of(self, rays, pose):
        """The scan's CellUpdate with its hits alone, no free cells: a map for scan matching,
        which needs only where the obstacles are, at a small part of a trace's cost."""
        cells, sums, counts = hit_cells(transform_points(pose, rays.hits), self.resolution, self.cell_shift)
        return CellUpdate(np.empty((0, 2), np.int64), cells, sums, counts)

    def occupied(self, cells):
        """Whether each lattice cell (N, 2) holds more hits than misses (False outside the array)."""
        height, width = self.log_odds.shape
        cols, rows = cells[:, 0] - self.offset[0], cells[:, 1] - self.offset[1]
        inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
        result = np.zeros(len(cells), dtype=bool)
        result[inside] = self.log_odds[rows[inside], cols[inside]] > 0.0
        return result

    def apply(self, update, sign=1):
        """Add (sign 1) or take back (sign -1) a scan's CellUpdate."""
        bounds = update.bounds()
        if bounds is None:
            return
        self.reserve(*bounds)
        for cells, value in ((update.free, self.free_log_odds), (update.hits, self.hit_log_odds)):
            if len(cells):
                flat = self._flat_indices(cells)
                self.log_odds.reshape(-1)[flat] += sign * value
                self.observations.reshape(-1)[flat] += sign
        if len(update.hits):
            flat = self._flat_indices(update.hits)
            self.hit_sums.reshape(-1, 2)[flat] += sign * update.hit_sums
            self.hit_counts.reshape(-1)[flat] += sign * update.hit_counts

    def _flat_indices(self, cells):
        """Indices of lattice cells (N, 2), inside the arrays, into the arrays flattened (views)."""
        return (cells[:, 1] - self.offset[1]) * self.log_odds.shape[1] + (cells[:, 0] - self.offset[0])

    def obstacles(self, low, size):
        """The cells of the lattice window low (i, j), size (w, h) that hold obstacle evidence, for
        scan matching: their rows and columns in the window, strength in (0, 1] (one net hit is
        full evidence) and offsets (K, 2), in cells, from their centres to the mean of their hits."""
        height, width = self.log_odds.shape
        src_low = np.maximum(low, self.offset)
        src_high = np.minimum(low + size, self.offset + (width, height))
        if not width or (src_high <= src_low).any():
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32), np.zeros((0, 2), np.float32)
        a, b, w = src_low - self.offset, src_high - self.offset, src_low - low
        window = (slice(a[1], b[1]), slice(a[0], b[0]))
        rows, cols = np.nonzero(self.log_odds[window] > 0.0)
        # One net hit is full evidence; unknown and free cells give none.
        strength = np.clip(self.log_odds[window][rows, cols] / self.hit_log_odds, 0.0, 1.0)
        evident = strength > 0.0
        rows, cols, strength = rows[evident], cols[evident], strength[evident]
        counts = self.hit_counts[window][rows, cols]
        offsets = np.zeros((len(rows), 2), dtype=np.float32)
        hit = counts > 0.5
        offsets[hit] = self.hit_sums[window][rows[hit], cols[hit]] / counts[hit, None] - 0.5
        return rows + w[1], cols + w[0], strength, offsets

    def to_occupancy_map(self, free_probability=0.45, margin=2):
        """The observed part of the grid as an OccupancyMap with 100 / 0 / -1 cells (as gmapping
        publishes; see occupancy_values)."""
        observed = self.observations > 0
        if not observed.any():
            return OccupancyMap(np.full((1, 1), -1, dtype=np.int8), self.resolution, self._corner(self.offset) + (0.0,))
        rows = np.flatnonzero(observed.any(axis=1))
        cols = np.flatnonzero(observed.any(axis=0))
        r0, r1 = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, observed.shape[0])
        c0, c1 = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, observed.shape[1])
        cells = occupancy_values(self.log_odds[r0:r1, c0:c1], observed[r0:r1, c0:c1], free_probability)
        return OccupancyMap(cells, self.resolution, self._corner(self.offset + (c0, r0)) + (0.0,))

    def _corner(self, cell):
        """(x, y) of the lower corner of lattice cell (i, j)."""
        return tuple(float((index - self.cell_shift) * self.resolution) for index in cell)


def occupancy_values(log_odds, observed, free_probability=0.45):
    """100 / 0 / -1 (occupied / free / unknown) per cell of a log-odds array; `observed` marks the
    cells some ray reached.

    Occupied: the cells that hold more hits than misses, by weight (log-odds above 0), as
    matching and tracing read the grid (LogOddsGrid.occupied); with the shipped 0.85 / -0.4, a
    cell that more than 32 % of the rays reaching it hit (gmapping's occ_thresh is 25 %). A wall
    seen at a grazing angle or from afar is hit by some of the rays that reach it and passed by
    others: at 65 % it went unknown, and AMCL, which sees only occupied cells, lost it (aces, a
    map of the even scans, severe odometry: 0.084 m against 0.050, bench_slam_real)."""
    cells = np.full(log_odds.shape, -1, dtype=np.int8)
    cells[observed & (log_odds > 0.0)] = 100
    cells[observed & (log_odds <= _logit(free_probability))] = 0
    return cells


def _logit(probability):
    return math.log(probability / (1.0 - probability))
