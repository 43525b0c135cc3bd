"""line_icp's line normals, whose closed form stands in for an eigen-decomposition."""
import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from turtlebot3c_slam.line_icp import line_normals


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
