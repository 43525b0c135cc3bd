"""Global path planning on a costmap: A* over the 8-connected grid, then shortcuts.

A step between cells costs its length times (1 + cost_weight · cell cost / 252), so the
path keeps away from obstacles when that is cheap and squeezes through when it must.
Cells at INSCRIBED cost or above (the robot would touch something) and unknown cells
are never entered. The grid path is then shortened by replacing runs of cells with
straight segments that are no costlier than the run they replace (string pulling), which
removes the 45°/90° zig-zag of grid paths without cutting closer to obstacles.
"""
import heapq
import math
from typing import List, Optional, Tuple

import numpy as np

from .costmap import INSCRIBED, Costmap

SQRT2 = math.sqrt(2.0)
_NEIGHBOURS = ((-1, -1, SQRT2), (-1, 0, 1.0), (-1, 1, SQRT2), (0, -1, 1.0),
               (0, 1, 1.0), (1, -1, SQRT2), (1, 0, 1.0), (1, 1, SQRT2))


class PlanningError(Exception):
    """No path: the message says why (start or goal blocked, or no connection)."""


def _nearest_free_cell(costs, row, col, max_cells):
    """The passable cell nearest to (row, col) within max_cells, or None."""
    height, width = costs.shape
    r0, r1 = max(0, row - max_cells), min(height, row + max_cells + 1)
    c0, c1 = max(0, col - max_cells), min(width, col + max_cells + 1)
    window = costs[r0:r1, c0:c1]
    rows, cols = np.nonzero(window < INSCRIBED)
    if rows.size == 0:
        return None
    rows, cols = rows + r0, cols + c0
    best = np.argmin((rows - row) ** 2 + (cols - col) ** 2)
    if (rows[best] - row) ** 2 + (cols[best] - col) ** 2 > max_cells ** 2:
        return None
    return int(rows[best]), int(cols[best])


def astar(costs, start, goal, cost_weight=3.0, passable=None) -> Optional[List[Tuple[int, int]]]:
    """Cells from start to goal (row, col) through `passable` cells (default: costs below
    INSCRIBED), or None."""
    height, width = costs.shape
    passable = (costs < INSCRIBED if passable is None else passable).ravel().tolist()
    step_factor = (1.0 + cost_weight * np.minimum(costs, 252).astype(float) / 252.0).ravel().tolist()
    start_index = start[0] * width + start[1]
    goal_index = goal[0] * width + goal[1]
    goal_row, goal_col = goal
    best = {start_index: 0.0}
    parent = {start_index: -1}
    frontier = [(0.0, 0.0, start_index)]
    closed = set()
    while frontier:
        _, cost_so_far, index = heapq.heappop(frontier)
        if index in closed:
            continue
        if index == goal_index:
            return _walk_back(parent, index, width)
        closed.add(index)
        row, col = divmod(index, width)
        for d_row, d_col, length in _NEIGHBOURS:
            n_row, n_col = row + d_row, col + d_col
            if n_row < 0 or n_row >= height or n_col < 0 or n_col >= width:
                continue
            neighbour = n_row * width + n_col
            if not passable[neighbour] or neighbour in closed:
                continue
            new_cost = cost_so_far + length * 0.5 * (step_factor[index] + step_factor[neighbour])
            if new_cost < best.get(neighbour, math.inf):
                best[neighbour] = new_cost
                parent[neighbour] = index
                dr, dc = abs(goal_row - n_row), abs(goal_col - n_col)
                heuristic = (dr + dc) + (SQRT2 - 2.0) * min(dr, dc)
                heapq.heappush(frontier, (new_cost + heuristic, new_cost, neighbour))
    return None


def _walk_back(parent, index, width):
    cells = []
    while index != -1:
        cells.append(divmod(index, width))
        index = parent[index]
    return cells[::-1]


def _segment_cells(a, b):
    """Cells (rows, cols arrays) touched by the straight segment between two cells."""
    steps = int(max(abs(b[0] - a[0]), abs(b[1] - a[1])) * 2) + 1
    t = np.linspace(0.0, 1.0, steps + 1)
    rows = np.round(a[0] + (b[0] - a[0]) * t).astype(int)
    cols = np.round(a[1] + (b[1] - a[1]) * t).astype(int)
    return rows, cols


def shortcut(costs, cells, slack=0):
    """Keep only the cells where the path must turn: a straight segment replaces a run of
    cells when its highest cost is no more than the run's highest cost (+ slack)."""
    if len(cells) <= 2:
        return list(cells)
    kept = [cells[0]]
    anchor = 0
    probe = 2
    while probe < len(cells):
        run_rows = [r for r, _ in cells[anchor:probe + 1]]
        run_cols = [c for _, c in cells[anchor:probe + 1]]
        run_max = int(costs[run_rows, run_cols].max())
        rows, cols = _segment_cells(cells[anchor], cells[probe])
        if int(costs[rows, cols].max()) > run_max + slack:
            kept.append(cells[probe - 1])
            anchor = probe - 1
        probe += 1
    kept.append(cells[-1])
    return kept


def densify(points, spacing):
    """Points every `spacing` metres along a polyline (N x 2), ends included."""
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        return points
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        length = float(np.hypot(*(b - a)))
        count = max(1, int(math.ceil(length / spacing)))
        t = np.arange(1, count + 1)[:, None] / count
        out.append(a + (b - a) * t)
    return np.vstack(out)


def path_length(points) -> float:
    points = np.asarray(points, dtype=float)
    if len(points) < 2:
        return 0.0
    return float(np.hypot(*np.diff(points, axis=0).T).sum())


class GlobalPlanner:
    def __init__(self, cost_weight=1.0, goal_search_radius=0.0, spacing=0.05, clearance_cost=175,
                 clearance_radius=0.4):
        """`goal_search_radius` (m): a goal in a blocked cell moves to the nearest free cell
        within it (0: such a goal is unreachable); the start may always move a little, since
        localisation noise can put the robot's centre inside the inscribed band.

        Paths first keep out of cells costlier than `clearance_cost` (175: 0.12 m beyond the
        robot's circle with cost_scaling_factor 3) (except within
        clearance_radius of the start and the goal), leaving the controller room to follow
        them with arcs; only where that finds no way do they use the whole free space."""
        self.clearance_cost = clearance_cost
        self.clearance_radius = clearance_radius
        self.cost_weight = cost_weight
        self.goal_search_radius = goal_search_radius
        self.spacing = spacing

    def _roomy(self, costs, info, start, goal):
        passable = costs < min(self.clearance_cost, INSCRIBED)
        reach = int(round(self.clearance_radius / info.resolution))
        for row, col in (start, goal):
            r0, c0 = max(0, row - reach), max(0, col - reach)
            window = costs[r0:row + reach + 1, c0:col + reach + 1]
            passable[r0:row + reach + 1, c0:col + reach + 1] |= window < INSCRIBED
        return passable

    def plan(self, costmap: Costmap, start_xy, goal_xy) -> np.ndarray:
        """Path (N x 2 world points, every `spacing` m) from start to goal; PlanningError if none."""
        info = costmap.info
        costs = costmap.costs
        start = tuple(int(v) for v in info.world_to_cell(*start_xy))
        goal = tuple(int(v) for v in info.world_to_cell(*goal_xy))
        if not info.contains(*goal):
            raise PlanningError("goal ({:.2f}, {:.2f}) is outside the map".format(*goal_xy))
        if not info.contains(*start):
            raise PlanningError("robot ({:.2f}, {:.2f}) is outside the map".format(*start_xy))
        if costs[goal] >= INSCRIBED:
            cells = int(self.goal_search_radius / info.resolution)
            moved = _nearest_free_cell(costs, goal[0], goal[1], cells) if cells > 0 else None
            if moved is None:
                raise PlanningError("goal ({:.2f}, {:.2f}) is in or too close to an obstacle or unknown space"
                                    .format(*goal_xy))
            goal = moved
        if costs[start] >= INSCRIBED:
            moved = _nearest_free_cell(costs, start[0], start[1], int(round(0.3 / info.resolution)))
            if moved is None:
                raise PlanningError("robot ({:.2f}, {:.2f}) is inside an obstacle on the costmap".format(*start_xy))
            start = moved
        cells = astar(costs, start, goal, self.cost_weight, self._roomy(costs, info, start, goal))
        if cells is None:
            cells = astar(costs, start, goal, self.cost_weight)
        if cells is None:
            raise PlanningError("no path from ({:.2f}, {:.2f}) to ({:.2f}, {:.2f}): the goal is cut off by obstacles"
                                .format(*start_xy[:2], *goal_xy[:2]))
        corners = shortcut(costs, cells)
        xs, ys = info.cell_to_world([r for r, _ in corners], [c for _, c in corners])
        points = np.column_stack([xs, ys])
        points[0] = start_xy
        if costs[info.world_to_cell(*goal_xy)] < INSCRIBED:
            points[-1] = goal_xy
        return densify(points, self.spacing)
