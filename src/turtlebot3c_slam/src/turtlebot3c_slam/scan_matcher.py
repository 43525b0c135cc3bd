"""Scan-to-map matching: a correlative search over rotations and translations with branch and bound.

The map side is a likelihood field over a window of the grid lattice: each cell holds how
well a scan endpoint falling there agrees with the map (1 on an obstacle, decaying over a
couple of cells). A pose's score is the mean field value under the scan's points.

The search is exhaustive over rotations (steps small enough that the farthest point moves
about one cell) and branch-and-bound over translations: precomputed maxima of the field over
2^h x 2^h blocks bound the score of every translation in a block, so whole blocks whose
bound cannot beat the best exact score found so far are skipped (Olson's multi-resolution
correlative matching, as in Cartographer's real-time loop closure). The likelihood field
knows where in each cell the hits were, so a coarse-looking grid still scores sub-cell
offsets of walls right. Pure numpy; no rospy.
"""
import math

import numpy as np

from turtlebot3c_common.se2 import transform_points, wrap_angle

FIELD_RADIUS = 2  # cells an obstacle's likelihood spreads
MAX_ANGLE_STEP = math.radians(2.0)  # the coarsest rotation step a search takes
SWEEP_STEP = 0.1  # rad between the rotations swept_bounds lays points at


def swept_bounds(points, pose, window_xy, window_theta):
    """Lowest and highest (x, y) that robot-frame points (N, 2) reach at any pose within
    +-window_xy (m) and +-window_theta (rad) of `pose`: the box of the points laid at rotations
    SWEEP_STEP or less apart, grown by the window and by how far an arc between two of them
    bulges beyond their chord."""
    count = int(math.ceil(window_theta / SWEEP_STEP))
    headings = pose[2] + np.linspace(-window_theta, window_theta, 2 * count + 1)[:, None]
    cos, sin = np.cos(headings), np.sin(headings)
    laid_x = pose[0] + cos * points[:, 0] - sin * points[:, 1]
    laid_y = pose[1] + sin * points[:, 0] + cos * points[:, 1]
    reach = float(np.max(np.hypot(points[:, 0], points[:, 1])))
    spacing = 2 * window_theta / max(2 * count, 1)
    slack = window_xy + reach * (1.0 - math.cos(spacing / 2))
    return np.array([laid_x.min(), laid_y.min()]) - slack, np.array([laid_x.max(), laid_y.max()]) + slack


def searched_cells(points, pose, window_xy, window_theta, resolution):
    """Lowest and highest lattice cell (i, j) robot-frame points can fall in when a search tries
    poses within +-window_xy, +-window_theta of `pose` (its last rotation step may overshoot)."""
    low, high = swept_bounds(points, pose, window_xy, window_theta + MAX_ANGLE_STEP)
    return np.floor(low / resolution).astype(np.int64), np.floor(high / resolution).astype(np.int64)


def sparse_likelihood_field(shape, rows, cols, strength, offsets, sigma_cells=1.0, radius=FIELD_RADIUS):
    """How well a point in each cell of a window `shape` (h, w) agrees with its obstacle cells
    (rows, cols), of strength in (0, 1] and with offsets (K, 2), in cells, from their centres to
    where their hits were.

    Each obstacle cell spreads its strength to the cells around with a Gaussian fall-off in the
    distance from their centres to where its hits were; a cell keeps the largest value. Sampled
    at cell centres and interpolated, the field peaks where the hits were, not at the centres of
    their cells, so matching is not biased by the grid. The work grows with the obstacle cells,
    not the window: a map is mostly free and unknown space."""
    height, width = shape
    values = np.asarray(strength).astype(np.float32)
    hit_x, hit_y = offsets[:, 0].astype(np.float32), offsets[:, 1].astype(np.float32)
    padded_width = width + 2 * radius
    field = np.zeros((height + 2 * radius, padded_width), dtype=np.float32)
    flat_field = field.reshape(-1)
    obstacles = (rows + radius) * padded_width + cols + radius
    scale = np.float32(-0.5 / sigma_cells ** 2)
    shifts = range(-radius, radius + 1)
    # The cell dx, dy away from an obstacle cell is this far (squared, per axis) from its hits.
    gaps_x = {dx: np.square(hit_x - np.float32(dx)) for dx in shifts}
    gaps_y = {dy: np.square(hit_y - np.float32(dy)) for dy in shifts}
    for dy in shifts:
        for dx in shifts:
            # Within one (dx, dy) every obstacle reaches a different cell, so plain indexing takes the max.
            reached = values * np.exp(scale * (gaps_x[dx] + gaps_y[dy]))
            target = obstacles + (dy * padded_width + dx)
            flat_field[target] = np.maximum(flat_field[target], reached)
    return field[radius:radius + height, radius:radius + width]


class MatchResult:
    def __init__(self, pose, score):
        self.pose = pose
        self.score = score  # mean field value under the points at pose, in [0, 1]

    def __repr__(self):
        return f"MatchResult(pose={self.pose}, score={self.score:.3f})"


class GridMatcher:
    """Matches point sets (robot frame) against one likelihood field (values in [0, 1]); `low`
    is the lattice (i, j) of field[0, 0] and `levels` the number of coarser maxima grids for
    branch and bound."""

    def __init__(self, field, low, resolution, levels=4, max_candidates=4000):
        self.resolution = float(resolution)
        self.levels = int(levels)
        self.max_candidates = int(max_candidates)
        self.pad = (1 << self.levels) + 1
        height, width = field.shape
        base = np.zeros((height + 2 * self.pad, width + 2 * self.pad), dtype=np.float32)
        base[self.pad:self.pad + height, self.pad:self.pad + width] = field
        self.low = np.asarray(low, dtype=np.int64) - self.pad  # lattice (i, j) of base[0, 0]
        self.pyramid = [base]
        self._penalty = None
        self._flat = None
        for level in range(1, self.levels + 1):
            self.pyramid.append(_block_maxima(self.pyramid[-1], 1 << (level - 1)))

    # --- scoring ---------------------------------------------------------------------------

    def _cell_indices(self, world_points):
        """Integer (col, row) of points (..., 2) in the padded arrays (unclipped)."""
        cells = np.floor(world_points / self.resolution).astype(np.int64)
        return cells[..., 0] - self.low[0], cells[..., 1] - self.low[1]

    def _scores(self, level, cols, rows, candidates):
        """Mean value at `level` for candidates (angle index, dx, dy) given per-angle base indices."""
        grid = self.pyramid[level]
        height, width = grid.shape
        angle, dx, dy = candidates[:, 0], candidates[:, 1], candidates[:, 2]
        if self._flat is not None:  # every candidate stays inside the grid: one flat lookup
            indices = self._flat[angle]  # a copy, (candidates, points)
            indices += (dy * width + dx).astype(indices.dtype)[:, None]
            # take and a sum rather than indexing and mean: the same values but for the last bits,
            # a fifth faster on core20's numpy, and this is where the search spends its time.
            return np.add.reduce(grid.ravel().take(indices), axis=1) * (1.0 / indices.shape[1])
        c = np.clip(cols[angle] + dx[:, None], 0, width - 1)
        r = np.clip(rows[angle] + dy[:, None], 0, height - 1)
        return grid[r, c].mean(axis=1)

    def _flat_indices(self, cols, rows, reach):
        """Flat indices of the points per angle when shifting them by -reach..reach (+ a block's
        stride) cells keeps all inside the grid, so lookups need no clipping; None otherwise.
        They are 32-bit where the grid allows: half the memory traffic of the lookups, which are
        most of the search's time."""
        height, width = self.pyramid[0].shape
        stride = 1 << self.levels
        if cols.min() - reach < 0 or rows.min() - reach < 0 or cols.max() + reach + stride >= width or \
                rows.max() + reach + stride >= height:
            return None
        flat = rows * width + cols
        return flat.astype(np.int32) if height * width < 2 ** 31 else flat

    def score(self, points, pose):
        """Mean field value of robot-frame points at pose (cell lookup, no interpolation)."""
        world = transform_points(pose, points)
        cols, rows = self._cell_indices(world[None])
        self._flat = None
        return float(self._scores(0, cols, rows, np.zeros((1, 3), dtype=np.int64))[0])

    def _interpolate(self, world):
        """Bilinearly interpolated field values at world points (N, 2), and their gradients by x and y (per m)."""
        u = world[:, 0] / self.resolution - 0.5 - self.low[0]  # field samples sit at cell centres
        v = world[:, 1] / self.resolution - 0.5 - self.low[1]
        grid = self.pyramid[0]
        height, width = grid.shape
        # np.minimum / np.maximum rather than np.clip: the same values, without np.clip's
        # overhead, which counts on a few hundred points per call.
        col = np.minimum(np.maximum(np.floor(u).astype(np.int64), 0), width - 2)
        row = np.minimum(np.maximum(np.floor(v).astype(np.int64), 0), height - 2)
        fu, fv = np.minimum(np.maximum(u - col, 0.0), 1.0), np.minimum(np.maximum(v - row, 0.0), 1.0)
        flat, corner = grid.reshape(-1), row * width + col
        f00, f10 = flat[corner], flat[corner + 1]
        f01, f11 = flat[corner + width], flat[corner + width + 1]
        bottom, top = f00 + fu * (f10 - f00), f01 + fu * (f11 - f01)
        values = bottom + fv * (top - bottom)
        d_u = (1 - fv) * (f10 - f00) + fv * (f11 - f01)
        d_v = top - bottom
        return values, d_u / self.resolution, d_v / self.resolution

    def refine(self, points, pose, iterations=8):
        """Sub-cell pose: Gauss-Newton on the interpolated field from `pose` (a search result).

        The correlative search is exact only to a cell and an angle step; a real robot's
        sparse scans would add those steps up into drift. Returns a MatchResult whose score
        is the interpolated mean field value; it never moves more than a cell or two.
        """
        current = np.array(pose, dtype=np.float64)
        values, grad_x, grad_y = self._interpolate(transform_points(current, points))
        best, best_score = current.copy(), float(values.mean())
        for _ in range(iterations):
            cos, sin = math.cos(current[2]), math.sin(current[2])
            d_theta = grad_x * (-sin * points[:, 0] - cos * points[:, 1]) + \
                grad_y * (cos * points[:, 0] - sin * points[:, 1])
            jacobian = np.column_stack((grad_x, grad_y, d_theta))
            residual = 1.0 - values
            hessian = jacobian.T @ jacobian
            step = np.linalg.solve(hessian + 1e-3 * np.diag(np.diag(hessian)) + 1e-9 * np.eye(3), jacobian.T @ residual)
            limit = max(abs(step[0]), abs(step[1])) / self.resolution
            if limit > 1.0:
                step /= limit
            current = current + step
            values, grad_x, grad_y = self._interpolate(transform_points(current, points))
            score = float(values.mean())
            if score <= best_score:
                break
            best, best_score = current.copy(), score
        if math.hypot(best[0] - pose[0], best[1] - pose[1]) > 2 * self.resolution:
            best, best_score = np.array(pose, dtype=np.float64), self._interpolated_score(points, pose)
        return MatchResult((float(best[0]), float(best[1]), wrap_angle(float(best[2]))), float(best_score))

    def _interpolated_score(self, points, pose):
        return float(self._interpolate(transform_points(pose, points))[0].mean())

    # --- search ----------------------------------------------------------------------------

    def match(self, points, prior, window_xy, window_theta, angle_step=None, prior_sigmas=None, min_score=0.0):
        """Best pose within +-window_xy (m) and +-window_theta (rad) of `prior` for `points` (N, 2).

        Rotations are tried every `angle_step` (default: the farthest point moves one cell),
        translations every cell. With prior_sigmas (m, rad), a pose's score is multiplied by a
        Gaussian of its distance from the prior, so where the scan cannot tell poses apart (a
        corridor, a doorway) the prior wins; ties always keep the prior. Poses that cannot score
        `min_score` are not searched: when none can, the result scores below it (a caller that
        would reject such a match anyway is spared most of the search: a loop-closure search
        that finds nothing is most of them).
        """
        if len(points) == 0:
            return MatchResult(tuple(prior), 0.0)
        if angle_step is None:
            reach = max(float(np.max(np.hypot(points[:, 0], points[:, 1]))), self.resolution)
            angle_step = min(max(self.resolution / reach, math.radians(0.25)), MAX_ANGLE_STEP)
        steps = int(math.ceil(window_theta / angle_step))
        angles = prior[2] + np.arange(-steps, steps + 1) * angle_step
        cos, sin = np.cos(angles)[:, None], np.sin(angles)[:, None]
        world = np.stack((prior[0] + cos * points[:, 0] - sin * points[:, 1],
                          prior[1] + sin * points[:, 0] + cos * points[:, 1]), axis=-1)
        cols, rows = self._cell_indices(world)
        reach = int(math.ceil(window_xy / self.resolution))
        self._flat = self._flat_indices(cols, rows, reach)
        self._penalty = None
        if prior_sigmas is not None:
            self._penalty = (self.resolution ** 2 / (2.0 * prior_sigmas[0] ** 2),
                             angle_step ** 2 / (2.0 * prior_sigmas[1] ** 2), steps)
        best_candidate, best_score = self._branch_and_bound(cols, rows, steps, reach, min_score)
        angle_index, dx, dy = best_candidate
        angle = wrap_angle(float(angles[angle_index]))
        pose = (prior[0] + dx * self.resolution, prior[1] + dy * self.resolution, angle)
        return MatchResult(pose, best_score)

    def _branch_and_bound(self, cols, rows, center_angle, reach, min_score):
        top = min(self.levels, max(0, int(math.ceil(math.log2(2 * reach + 1)))))
        stride = 1 << top
        starts = np.arange(-reach, reach + 1, stride)
        a, x, y = np.meshgrid(np.arange(cols.shape[0]), starts, starts, indexing="ij")
        candidates = np.column_stack((a.ravel(), x.ravel(), y.ravel()))
        prior_candidate = np.array([[center_angle, 0, 0]])
        best_score = float(self._exact_scores(cols, rows, prior_candidate)[0])
        best = prior_candidate[0]
        bounds = self._scores(top, cols, rows, candidates)
        greedy, greedy_score = self._descend(cols, rows, candidates[np.argmax(bounds)], top, reach)
        if greedy_score > best_score:
            best, best_score = greedy, greedy_score
        for level in range(top, 0, -1):
            keep = (bounds > best_score) & (bounds >= min_score)
            if not keep.any():
                return best, best_score
            candidates, bounds = candidates[keep], bounds[keep]
            if len(candidates) > self.max_candidates:
                order = np.argsort(-bounds)[:self.max_candidates]
                candidates = candidates[order]
            candidates = self._children(candidates, level, reach)
            bounds = self._scores(level - 1, cols, rows, candidates)
        bounds = self._with_penalty(bounds, candidates)
        index = int(np.argmax(bounds))
        if bounds[index] > best_score:
            best, best_score = candidates[index], float(bounds[index])
        return best, best_score

    def _exact_scores(self, cols, rows, candidates):
        return self._with_penalty(self._scores(0, cols, rows, candidates), candidates)

    def _with_penalty(self, scores, candidates):
        """Scores times the prior's Gaussian (at most 1, so coarser levels' bounds stay bounds)."""
        if self._penalty is None:
            return scores
        per_cell, per_step, center = self._penalty
        shift = candidates[:, 1] ** 2 + candidates[:, 2] ** 2
        turn = (candidates[:, 0] - center) ** 2
        return scores * np.exp(-(per_cell * shift + per_step * turn))

    def _children(self, candidates, level, reach):
        half = 1 << (level - 1)
        quarters = np.array([[0, 0, 0], [0, 0, half], [0, half, 0], [0, half, half]], dtype=candidates.dtype)
        children = (quarters[:, None, :] + candidates[None]).reshape(-1, 3)  # each quarter's, in turn
        return children[(children[:, 1] <= reach) & (children[:, 2] <= reach)]

    def _descend(self, cols, rows, candidate, level, reach):
        candidates = candidate[None]
        for current in range(level, 0, -1):
            children = self._children(candidates, current, reach)
            scores = self._scores(current - 1, cols, rows, children)
            candidates = children[np.argmax(scores)][None]
        return candidates[0], float(self._exact_scores(cols, rows, candidates)[0])


def _block_maxima(grid, half):
    """Each cell's maximum with the cells `half` to its right, above, and both: from blocks of
    half x half cells, blocks twice as wide (the last `half` columns and rows keep their own).

    The maxima are taken over the flat array viewed as int32: a field's values are never
    negative, and such floats order as their bits do, so the maxima are the same. core20's
    numpy takes float32 maxima row by row five times slower than int32 ones over one flat run,
    and these grids took a sixth of its SLAM's time."""
    bits = grid.view(np.int32)
    wider = _maxima_with_later(bits, half)
    wider[:, -half:] = bits[:, -half:]  # flat, a row's last cells met the next row's first
    return _maxima_with_later(wider, half * grid.shape[1]).view(np.float32)


def _maxima_with_later(array, shift):
    """Each element's maximum with the one `shift` places later in the flat (C-ordered) array;
    the last `shift` keep their own."""
    flat = array.reshape(-1)
    result = np.empty_like(flat)
    np.maximum(flat[:-shift], flat[shift:], out=result[:-shift])
    result[-shift:] = flat[-shift:]
    return result.reshape(array.shape)
