"""Point-to-line ICP of a 2-D point set against another. Pure numpy and scipy; no rospy.

Each target point carries the normal of a line fitted through its nearest neighbours, and a
source point pulls the pose only across that line, so a wall's points may slide along it: on
laser scans of walls this converges from much farther off, and more precisely, than
point-to-point ICP. Residuals are Huber-weighted, so a few points without a true partner
(a person walking by, an open door) barely move the result. A point pairs only with a line whose
face its own scanner sees too, never with the far face of a wall; and, when asked for (the
refinement's fine matches), only with a line that reaches it.
"""

import numpy as np
from scipy.spatial import cKDTree

from turtlebot3c_common.se2 import transform_points

NORMAL_NEIGHBOURS = 5   # points a local line is fitted through
PAIR_DISTANCE = 0.2     # m: a point farther from the target has no partner there
HUBER = 0.03            # m
MIN_PAIRS = 50
ITERATIONS = 30
ON_LINE = 0.05          # m: a point this close to its partner's line lies on it
SETTLED = 1e-6          # m and rad: a smaller step ends the iterations
DAMPING = 1e-6 * np.eye(3)  # keeps a corridor's loose direction solvable


class LineCloud:
    """Target points (N, 2) of a scan, in a frame whose origin is where it was taken from (the
    robot's), with a k-d tree, a line normal per point, turned towards that origin, and how far
    the points its line was fitted through reach along it on either side (N, 2: m, the first
    negative or 0)."""

    def __init__(self, points):
        self.points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self.tree = cKDTree(self.points)
        if len(self.points) < NORMAL_NEIGHBOURS:
            self.normals, self.reach = np.zeros_like(self.points), np.zeros_like(self.points)
            return
        _, neighbours = self.tree.query(self.points, k=NORMAL_NEIGHBOURS)
        normals = _normals(self.points[neighbours])
        away = np.einsum("ij,ij->i", normals, self.points) > 0
        self.normals = np.where(away[:, None], -normals, normals)
        along = np.einsum("nkj,nj->nk", self.points[neighbours] - self.points[:, None], _along(self.normals))
        self.reach = np.column_stack((along.min(axis=1), along.max(axis=1)))

    def pairs(self, laid, viewpoint, within_lines=False):
        """For points (M, 2) laid in the target's frame, seen from `viewpoint` (x, y) there: which
        have a partner within PAIR_DISTANCE, their partners' normals, the signed point-to-line
        distances and the partners' indices; None with too few partners. A point seen from the
        other side of its partner's line has none: it lies on the far face of a wall (seen from
        the next room), a wall's thickness off, and paired it would pull the scans together by
        as much. With `within_lines`, nor has a point beyond the end of its partner's line (past
        a pillar's edge as the target saw it, a door frame, the last hit before a shadow):
        paired with the end point, it is pulled across a line that does not reach it, always to
        the same side. Round turtlebot3_world's pillars that bent scan_refinement's poses 8-9 mm
        RMS from the truth they started on; 2-3 mm without. ICP from farther off (a loop
        closure's checks, the benchmarks' judge of closures) keeps those pairs: from tenths of a
        metre off they are what pull a scan in, and without them the loop closure's checks
        passed more closures (on the infinite-corridor log 156 against 140, one more that the
        reference disagrees with)."""
        if len(self.points) < NORMAL_NEIGHBOURS:
            return None
        # Bounded, the tree gives up on a point as soon as nothing can be that near: the same
        # partners, and on scipy 1.3 the refinement at the end takes 7 % less time.
        distance, partner = self.tree.query(laid, distance_upper_bound=PAIR_DISTANCE)
        near = distance < PAIR_DISTANCE
        candidates = np.flatnonzero(near)
        partners = partner[candidates]
        kept = np.einsum("ij,ij->i", np.asarray(viewpoint[:2], dtype=np.float64) - laid[candidates],
                         self.normals[partners]) > 0
        if within_lines:
            kept &= self._reaches(laid[candidates], partners)
        near[candidates[~kept]] = False
        if np.count_nonzero(near) < MIN_PAIRS:
            return None
        partner = partner[near]
        normals = self.normals[partner]
        return near, normals, self.distances(laid[near], partner, normals), partner

    def _reaches(self, points, partners):
        """Whether the line of each of `partners` reaches as far along it as the point beside it."""
        along = np.einsum("ij,ij->i", points - self.points[partners], _along(self.normals[partners]))
        return (along >= self.reach[partners, 0]) & (along <= self.reach[partners, 1])

    def distances(self, points, partner, normals):
        """Signed distances of points (M, 2), laid in the target's frame, from their partners' lines."""
        return np.einsum("ij,ij->i", points - self.points[partner], normals)

    def points_on_lines(self, points, pose):
        """How many of `points` (their own frame), laid at `pose`, lie on the target's lines."""
        paired = self.pairs(transform_points(tuple(pose), points), pose)
        return 0 if paired is None else int((np.abs(paired[2]) < ON_LINE).sum())


def line_normals(points):
    """The normal of a line fitted through each point (N, 2) and its nearest neighbours."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(points) < NORMAL_NEIGHBOURS:
        return np.zeros_like(points)
    _, neighbours = cKDTree(points).query(points, k=NORMAL_NEIGHBOURS)
    return _normals(points[neighbours])


def _normals(groups):
    """The normal of the line through each group of points (N, K, 2)."""
    centred = groups - groups.mean(axis=1, keepdims=True)
    return _least_spread(centred[..., 0], centred[..., 1])


def _along(normals):
    """The directions (N, 2) of the lines across which `normals` stand: each a quarter turn on."""
    return np.column_stack((-normals[:, 1], normals[:, 0]))


def _least_spread(x, y):
    """The unit direction (N, 2) in which each row of centred points (x and y, N x K) spreads
    least: across the line through them. It is the eigenvector of the smaller eigenvalue of
    their scatter [[a, b], [b, c]], here in closed form: a tenth of np.linalg.eigh's time on a
    scan's few hundred matrices, and the same direction to 1e-15. With d = a - c and
    r = hypot(d, 2b), the line runs along (d + r, 2b), or (2b, r - d), whichever is not near
    zero (the first where d >= 0); the normal is that turned a quarter turn."""
    a, b, c = np.einsum("nk,nk->n", x, x), np.einsum("nk,nk->n", x, y), np.einsum("nk,nk->n", y, y)
    d = a - c
    r = np.hypot(d, 2.0 * b)
    normals = np.where((d >= 0)[:, None], np.column_stack((-2.0 * b, d + r)), np.column_stack((d - r, 2.0 * b)))
    # Points with no direction (all in one place) get no normal rather than a made-up one.
    return normals / np.maximum(np.hypot(normals[:, 0], normals[:, 1]), np.finfo(np.float64).tiny)[:, None]


def align(target, points, start, iterations=ITERATIONS, settled=SETTLED, keep_pairs=0.0, within_lines=False):
    """The pose (x, y, theta) of `points` (their own frame) in `target`'s frame that lays them on
    its lines, from `start`, and the Gauss-Newton Hessian there (in the target's frame, per m^2 of
    residual); None when too few points find a partner. `within_lines`: see LineCloud.pairs. It
    stops after a step smaller than `settled` (m and rad). After a step smaller than
    `keep_pairs` (m and rad) the points keep their partners rather than look them up again: so
    small a step changes few of them, and the lookup is most of an iteration's time."""
    pose = np.array(start, dtype=np.float64)
    hessian = None
    kept = False
    for _ in range(iterations):
        laid = transform_points(tuple(pose), points)
        if not kept:
            paired = target.pairs(laid, pose, within_lines)
            if paired is None:
                return None
            near, normals, residuals, partner = paired
        else:
            residuals = target.distances(laid[near], partner, normals)
        # As theta grows a point moves at right angles to its lever from the pose: (-ly, lx).
        lever = laid[near] - pose[:2]
        jacobian = np.empty((len(normals), 3))
        jacobian[:, :2] = normals
        jacobian[:, 2] = normals[:, 1] * lever[:, 0] - normals[:, 0] * lever[:, 1]
        weighted = jacobian.T * np.minimum(1.0, HUBER / np.maximum(np.abs(residuals), 1e-12))
        hessian = weighted @ jacobian
        step = -np.linalg.solve(hessian + DAMPING, weighted @ residuals)
        pose += step
        size = np.abs(step).max()
        if size < settled:
            break
        kept = size < keep_pairs
    return tuple(float(value) for value in pose), hessian
