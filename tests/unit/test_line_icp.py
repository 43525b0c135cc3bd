"""line_icp: the line normals, whose closed form stands in for an eigen-decomposition, and the alignment."""
import copy
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from turtlebot3c_common.se2 import inverse, transform_points
from turtlebot3c_slam.line_icp import LineCloud, align, line_normals


@pytest.mark.parametrize("heading", [0.0, 0.3, math.pi / 4, math.pi / 2, 2.0, -math.pi / 2, math.pi])
def test_points_along_a_wall_get_normals_across_it(heading):
    along = np.linspace(-1.0, 1.0, 21)
    wall = np.column_stack((along * math.cos(heading), along * math.sin(heading))) + (2.0, -1.0)
    normals = line_normals(wall)
    assert np.allclose(np.hypot(normals[:, 0], normals[:, 1]), 1.0)
    assert np.allclose(normals @ (math.cos(heading), math.sin(heading)), 0.0, atol=1e-12)


def test_the_normals_are_the_scatters_least_eigenvectors():
    rng = np.random.default_rng(4)
    points = rng.normal(size=(300, 2)) * (1.0, 0.2)
    normals = line_normals(points)
    _, neighbours = cKDTree(points).query(points, k=5)
    centred = points[neighbours] - points[neighbours].mean(axis=1, keepdims=True)
    _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", centred, centred))
    assert np.allclose(np.abs(np.einsum("ij,ij->i", normals, vectors[:, :, 0])), 1.0, atol=1e-9)


def test_points_all_in_one_place_get_no_normal():
    normals = line_normals(np.tile((1.5, 0.5), (6, 1)))
    assert np.array_equal(normals, np.zeros((6, 2)))


def room_walls(first, spacing, noise, rng):
    """Points along the walls of a 4 x 3 m room around the origin, one every `spacing` m from `first`."""
    corners = np.array([(-2.0, -1.5), (2.0, -1.5), (2.0, 1.5), (-2.0, 1.5), (-2.0, -1.5)])
    walls = []
    for start, end in zip(corners[:-1], corners[1:]):
        along = np.arange(first, np.hypot(*(end - start)), spacing) / np.hypot(*(end - start))
        walls.append(start + along[:, None] * (end - start))
    points = np.concatenate(walls)
    return points + rng.normal(0.0, noise, points.shape)


def aligned_counting_lookups(target, points, keep_pairs):
    """align's pose from the origin, and how many times it looked the points' partners up."""
    lookups = []
    counting = copy.copy(target)

    def counting_pairs(laid, viewpoint, within_lines):
        lookups.append(laid)
        return target.pairs(laid, viewpoint, within_lines)
    counting.pairs = counting_pairs
    pose, _ = align(counting, points, (0.0, 0.0, 0.0), keep_pairs=keep_pairs)
    return pose, len(lookups)


def test_a_scan_is_aligned_on_the_walls_it_saw_and_keeping_its_pairs_spares_lookups():
    rng = np.random.default_rng(9)
    target = LineCloud(room_walls(0.0, 0.02, 0.002, rng))
    truth = (0.12, -0.08, 0.06)
    # The room as seen from `truth`: other points along the same walls, in that pose's frame.
    points = transform_points(inverse(truth), room_walls(0.011, 0.03, 0.002, rng))
    afresh, afresh_lookups = aligned_counting_lookups(target, points, keep_pairs=0.0)
    kept, kept_lookups = aligned_counting_lookups(target, points, keep_pairs=5e-3)
    for pose in (afresh, kept):
        assert pose[:2] == pytest.approx(truth[:2], abs=2e-3)
        assert pose[2] == pytest.approx(truth[2], abs=1e-3)
    assert kept_lookups < afresh_lookups  # 3 against 7


def test_within_lines_a_point_beyond_the_end_of_a_wall_has_no_partner_on_it():
    """Paired with the wall's last point, a point past its end would be pulled across a line
    that does not reach it (a pillar's edge, a door frame, the last hit before a shadow): the
    refinement asks for pairs within lines. A loop closure's checks, which align from farther
    off, pair it all the same."""
    wall = LineCloud(np.column_stack((np.arange(0.0, 1.001, 0.02), np.full(51, 1.0))))
    along = np.arange(-0.155, 1.16, 0.01)
    points = np.column_stack((along, np.full(len(along), 0.99)))
    near, _, residuals, _ = wall.pairs(points, (0.5, 0.0), within_lines=True)
    assert np.array_equal(near, (along > 0.0) & (along < 1.0))
    assert residuals == pytest.approx(0.01)  # 1 cm nearer the scanner than the wall
    assert wall.pairs(points, (0.5, 0.0))[0].all()
