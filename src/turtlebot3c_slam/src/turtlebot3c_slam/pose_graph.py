"""A 2-D pose graph and its least-squares optimisation (Gauss-Newton). Pure numpy; no rospy.

Nodes are poses (x, y, yaw) in the map frame; an edge says "node j seen from node i is at
`measurement`", with a 3x3 information matrix. Loop-closure edges get a Huber kernel, so
one wrong closure bends the graph less than it would under plain least squares. The first
node is held fixed. The normal equations are sparse (block tridiagonal along the route, plus
a block per loop closure) and solved with SciPy's sparse LU, so thousands of keyframes take
well under a second.
"""

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.linalg import spsolve

from turtlebot3c_common.se2 import cos_sin, wrap_angle

# The Hessian is symmetric, so its LU keeps least fill-in under a minimum-degree ordering of
# A^T + A; SciPy's default (COLAMD) orders for A^T A. On freiburg-079's refinement graph (1335
# nodes) each solve takes half the time, for the same poses but for the last bits.
FILL_REDUCING_ORDER = "MMD_AT_PLUS_A"


def diagonal_information(sigma_xy, sigma_theta):
    """The information matrix of a measurement with independent errors of these sigmas (m, rad)."""
    return np.diag([1.0 / sigma_xy ** 2, 1.0 / sigma_xy ** 2, 1.0 / sigma_theta ** 2])


class Edge:
    def __init__(self, i, j, measurement, information, robust=False):
        self.i, self.j = int(i), int(j)
        self.measurement = tuple(float(v) for v in measurement)
        self.information = np.asarray(information, dtype=np.float64)
        self.robust = robust


class PoseGraph:
    def __init__(self, huber_delta=2.0):
        self.poses = np.zeros((0, 3))
        self.edges = []
        self.huber_delta = huber_delta

    def add_node(self, pose):
        self.poses = np.vstack((self.poses, np.asarray(pose, dtype=np.float64)[None]))
        return len(self.poses) - 1

    def add_edge(self, i, j, measurement, information, robust=False):
        self.edges.append(Edge(i, j, measurement, information, robust))

    def _arrays(self):
        i = np.array([edge.i for edge in self.edges])
        j = np.array([edge.j for edge in self.edges])
        measurement = np.array([edge.measurement for edge in self.edges])
        information = np.array([edge.information for edge in self.edges])
        robust = np.array([edge.robust for edge in self.edges])
        return i, j, measurement, information, robust

    def _errors_and_jacobians(self, i, j, measurement):
        """Errors (E, 3) of all edges and their Jacobians (E, 3, 3) by node i and node j."""
        xi, xj = self.poses[i], self.poses[j]
        ci, si = cos_sin(xi[:, 2])
        cz, sz = cos_sin(measurement[:, 2])
        dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
        # j in i's frame, then its difference to the measurement in the measurement's frame
        lx, ly = ci * dx + si * dy, -si * dx + ci * dy
        ex, ey = lx - measurement[:, 0], ly - measurement[:, 1]
        error = np.column_stack((cz * ex + sz * ey, -sz * ex + cz * ey,
                                 wrap_angle(xj[:, 2] - xi[:, 2] - measurement[:, 2])))
        rot = np.zeros((len(i), 2, 2))       # R_z^T R_i^T
        rot[:, 0, 0] = cz * ci - sz * si
        rot[:, 0, 1] = cz * si + sz * ci
        rot[:, 1, 0] = -(cz * si + sz * ci)
        rot[:, 1, 1] = cz * ci - sz * si
        # derivative of R_i^T (t_j - t_i) by theta_i is (ly, -lx); then rotate by R_z^T
        dtheta = np.column_stack((cz * ly - sz * lx, -sz * ly - cz * lx))
        a = np.zeros((len(i), 3, 3))
        b = np.zeros((len(i), 3, 3))
        a[:, :2, :2] = -rot
        a[:, :2, 2] = dtheta
        a[:, 2, 2] = -1.0
        b[:, :2, :2] = rot
        b[:, 2, 2] = 1.0
        return error, a, b

    def edge_errors(self):
        """(E, 3) error of each edge at the current poses: x, y in the measurement's frame, yaw."""
        if not self.edges:
            return np.zeros((0, 3))
        i, j, measurement, _, _ = self._arrays()
        return self._errors_and_jacobians(i, j, measurement)[0]

    def chi2(self):
        if not self.edges:
            return 0.0
        i, j, measurement, information, _ = self._arrays()
        error = self._errors_and_jacobians(i, j, measurement)[0]
        return float(np.einsum("ea,eab,eb->", error, information, error))

    def optimize(self, iterations=10, tolerance=1e-6):
        """Move the poses to minimise the (robustified) weighted squared errors; returns the iterations run."""
        count = len(self.poses)
        if count < 2 or not self.edges:
            return 0
        i, j, measurement, information, robust = self._arrays()
        block = np.arange(3)
        size = 3 * count
        # Row and column of every entry of the four 3x3 blocks each edge adds to the Hessian.
        rows = np.concatenate([np.broadcast_to((3 * a)[:, None, None] + block[None, :, None], (len(i), 3, 3))
                               for a in (i, i, j, j)]).ravel()
        cols = np.concatenate([np.broadcast_to((3 * b)[:, None, None] + block[None, None, :], (len(i), 3, 3))
                               for b in (i, j, i, j)]).ravel()
        anchor = np.arange(3)
        rows = np.concatenate((rows, anchor))
        cols = np.concatenate((cols, anchor))
        done = 0
        while done < iterations:
            done += 1
            error, a, b = self._errors_and_jacobians(i, j, measurement)
            chi = np.sqrt(np.maximum(np.einsum("ea,eab,eb->e", error, information, error), 0.0))
            scale = np.where(robust & (chi > self.huber_delta), self.huber_delta / np.maximum(chi, 1e-12), 1.0)
            weighted = information * scale[:, None, None]
            at_w = np.einsum("eba,ebc->eac", a, weighted)
            bt_w = np.einsum("eba,ebc->eac", b, weighted)
            values = np.concatenate([(at_w @ a).ravel(), (at_w @ b).ravel(), (bt_w @ a).ravel(), (bt_w @ b).ravel(),
                                     np.full(3, 1e9)])  # the first node holds the map frame in place
            hessian = coo_matrix((values, (rows, cols)), shape=(size, size)).tocsc()  # duplicates are summed
            gradient = np.zeros(size)
            np.add.at(gradient, (3 * i)[:, None] + block, np.einsum("eab,eb->ea", at_w, error))
            np.add.at(gradient, (3 * j)[:, None] + block, np.einsum("eab,eb->ea", bt_w, error))
            step = spsolve(hessian, -gradient, permc_spec=FILL_REDUCING_ORDER).reshape(-1, 3)
            self.poses += step
            self.poses[:, 2] = wrap_angle(self.poses[:, 2])
            if np.abs(step).max() < tolerance:
                break
        return done

