"""Maps whose YAML origin has a yaw: map_server puts the yaw in the OccupancyGrid's origin,
and the navigation's map layers (costmaps, AMCL's likelihood field) place every cell where
that rotated grid puts it."""
import math

import genpy
import numpy as np
import pytest

from turtlebot3c_maps.map_files import OccupancyMap
from turtlebot3c_maps.map_messages import grid_from_msg, occupancy_grid_msg
from turtlebot3c_navigation.navigation_stack import axis_aligned, map_layers
from turtlebot3c_sim.evaluation import ground_truth_window

RESOLUTION = 0.1


def grid_with_obstacle(row, col, height=10, width=20):
    data = np.zeros((height, width), dtype=np.int8)
    data[row, col] = 100
    return data


def rotated_cell_centre(row, col, origin):
    """Where map_server's grid with this origin puts the centre of cell (row, col)."""
    x0, y0, yaw = origin
    lx, ly = (col + 0.5) * RESOLUTION, (row + 0.5) * RESOLUTION
    return x0 + math.cos(yaw) * lx - math.sin(yaw) * ly, y0 + math.sin(yaw) * lx + math.cos(yaw) * ly


def test_map_server_grid_carries_the_origin_yaw():
    occupancy_map = OccupancyMap(grid_with_obstacle(2, 15), RESOLUTION, (1.0, -0.5, 0.7))
    _, _, origin = grid_from_msg(occupancy_grid_msg(occupancy_map, "map", genpy.Time(0)))
    assert origin == pytest.approx((1.0, -0.5, 0.7), abs=1e-9)


def test_obstacle_of_a_quarter_turned_map_lands_where_the_rotated_grid_puts_it():
    origin = (1.0, -0.5, math.pi / 2)
    layers = map_layers(grid_with_obstacle(2, 15), RESOLUTION, origin)
    x, y = rotated_cell_centre(2, 15, origin)
    row, col = layers.info.world_to_cell(x, y)
    assert layers.occupied[row, col]
    assert layers.occupied.sum() <= 2  # grown by at most a cell where the lattices meet
    assert (layers.info.width, layers.info.height) == (10, 20)  # the grid turned on its side
    assert not layers.unknown.any()


def test_every_cell_of_an_obliquely_turned_map_keeps_its_place_and_outside_it_is_unknown():
    origin = (-2.0, 3.0, 0.5)
    data = np.zeros((10, 20), dtype=np.int8)
    data[::3, ::4] = 100
    layers = map_layers(data, RESOLUTION, origin)
    for row, col in zip(*np.nonzero(data)):
        x, y = rotated_cell_centre(row, col, origin)
        new_row, new_col = layers.info.world_to_cell(x, y)
        assert layers.occupied[new_row, new_col], (row, col)
    assert layers.unknown[0, 0] and layers.unknown[-1, -1]  # corners of the box around the turned grid
    assert (~layers.unknown).sum() >= data.size
    assert layers.occupied.sum() <= 4 * np.count_nonzero(data)  # each obstacle cell grows by at most a cell


def test_a_map_without_yaw_keeps_its_grid_and_origin():
    data = grid_with_obstacle(2, 15)
    resampled, origin = axis_aligned(data, RESOLUTION, (1.0, -0.5, 0.0))
    assert resampled is data or np.array_equal(resampled, data)
    assert origin == (1.0, -0.5, 0.0)
    layers = map_layers(data, RESOLUTION, (1.0, -0.5, 0.0))
    assert (layers.info.origin_x, layers.info.origin_y) == (1.0, -0.5)
    assert layers.occupied[2, 15] and layers.occupied.sum() == 1


def test_slam_evaluation_refuses_a_turned_map_with_a_clear_reason_and_takes_an_unturned_one():
    with pytest.raises(ValueError, match="origin yaw 0.700"):
        ground_truth_window(OccupancyMap(grid_with_obstacle(2, 15), RESOLUTION, (1.0, -0.5, 0.7)))
    assert ground_truth_window(OccupancyMap(grid_with_obstacle(2, 15), RESOLUTION, (1.0, -0.5, 0.0))) == \
        ((1.0, -0.5), 20, 10)
