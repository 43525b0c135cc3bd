"""Simulator worlds: files, ray casting against closed-form geometry, collision, rasterisation."""
import math

import numpy as np
import pytest

from turtlebot3c_sim.world import WorldError, load_world, world_from_description


def single_wall_world(x=2.0):
    return world_from_description({
        "spawn": [0.0, 0.0, 0.0],
        "obstacles": [{"type": "wall", "from": [x, -10.0], "to": [x, 10.0], "thickness": 0.1}]})


def test_turtlebot3_world_has_nine_pillars_five_hexagons_and_a_hexagonal_wall():
    world = load_world("turtlebot3_world")
    assert len(world.circle_radii) == 9
    assert np.allclose(world.circle_radii, 0.15)
    assert {tuple(center) for center in np.round(world.circle_centers, 3)} == {
        (x, y) for x in (-1.1, 0.0, 1.1) for y in (-1.1, 0.0, 1.1)}
    ring_sizes = sorted(len(ring) for solid in world.solids for ring in solid)
    assert ring_sizes == [6] * 7  # five hexagons + inner and outer wall rings
    assert world.spawn_pose == (-2.0, -0.5, 0.0)


def test_turtlebot3_world_inner_wall_is_flat_at_y_2_54():
    world = load_world("turtlebot3_world")
    up = world.raycast(0.55, 1.5, math.pi / 2, 3.5)
    assert up == pytest.approx(2.54 - 1.5, abs=1e-3)


def test_every_world_loads_and_its_spawn_pose_is_free():
    for name in ("turtlebot3_world", "empty", "house"):
        world = load_world(name)
        x, y, _ = world.spawn_pose
        assert not world.collides(x, y, 0.25), name


def test_unknown_world_names_the_known_ones():
    with pytest.raises(WorldError, match="known worlds: .*house.*turtlebot3_world"):
        load_world("moon_base")


def test_invalid_obstacle_is_rejected_with_its_index():
    with pytest.raises(WorldError, match="obstacle 1 .*radius must be positive"):
        world_from_description({"bounds": [0, 0, 1, 1], "obstacles": [
            {"type": "circle", "center": [0, 0], "radius": 1.0},
            {"type": "circle", "center": [0, 0], "radius": -1.0}]})
    with pytest.raises(WorldError, match="unknown type 'blob'"):
        world_from_description({"obstacles": [{"type": "blob"}]})


def test_world_file_given_by_path(tmp_path):
    path = tmp_path / "one_pillar.yaml"
    path.write_text("spawn: [0, 0, 0]\nobstacles:\n  - {type: circle, center: [1.0, 0.0], radius: 0.2}\n")
    world = load_world(str(path))
    assert world.raycast(0.0, 0.0, 0.0, 3.5) == pytest.approx(0.8)


def test_rays_hit_a_wall_at_distance_over_cosine():
    world = single_wall_world(2.0)
    angles = np.radians(np.arange(-60, 61, 5))
    ranges = world.raycast(0.0, 0.0, angles, 10.0)
    assert np.allclose(ranges, 1.95 / np.cos(angles))


def test_rays_away_from_everything_return_inf_and_ranges_stop_at_max_range():
    world = single_wall_world(2.0)
    assert np.isinf(world.raycast(0.0, 0.0, math.pi, 10.0))
    assert np.isinf(world.raycast(0.0, 0.0, 0.0, 1.9))
    assert np.isinf(load_world("empty").raycast(0.0, 0.0, np.linspace(0, 6, 50), 3.5)).all()


def test_rays_hit_a_circle_at_its_near_side_and_from_inside_at_the_far_side():
    world = world_from_description({"obstacles": [{"type": "circle", "center": [2.0, 0.0], "radius": 0.5}]})
    assert world.raycast(0.0, 0.0, 0.0, 5.0) == pytest.approx(1.5)
    tangent = math.asin(0.5 / 2.0)
    assert np.isfinite(world.raycast(0.0, 0.0, tangent - 1e-6, 5.0))
    assert np.isinf(world.raycast(0.0, 0.0, tangent + 1e-6, 5.0))
    assert world.raycast(2.0, 0.0, 1.0, 5.0) == pytest.approx(0.5)


def test_raycast_keeps_the_shape_of_its_angles():
    world = load_world("turtlebot3_world")
    assert world.raycast(-2.0, -0.5, np.zeros((3, 4)), 3.5).shape == (3, 4)


def test_collision_of_discs_and_polygons():
    world = single_wall_world(2.0)
    assert world.collides(1.8, 0.0, 0.16)
    assert not world.collides(1.8, 0.0, 0.14)
    assert world.collides(2.0, 0.0, 0.01)  # inside the wall
    square = np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])
    assert not world.polygon_collides(square + (1.8, 0.0))
    assert world.polygon_collides(square + (1.9, 0.0))
    pillar = world_from_description({"obstacles": [{"type": "circle", "center": [0.0, 0.0], "radius": 0.05}]})
    assert pillar.polygon_collides(square)  # an obstacle wholly under the polygon
    assert pillar.polygon_collides(square + (0.14, 0.0))
    assert not pillar.polygon_collides(square + (0.16, 0.0))


def test_rasterised_pillar_covers_its_area():
    world = world_from_description({"obstacles": [{"type": "circle", "center": [0.0, 0.0], "radius": 0.5}]})
    grid = world.rasterize(0.01, (-1.0, -1.0), 200, 200)
    assert grid.shape == (200, 200)
    assert grid.sum() * 1e-4 == pytest.approx(math.pi * 0.25, rel=0.03)
    assert grid[100, 100] and not grid[0, 0]


def test_rasterised_rows_are_y():
    world = single_wall_world(0.5)
    grid = world.rasterize(0.1, (-1.0, -2.0), 20, 40)
    occupied_columns = np.flatnonzero(grid.any(axis=0))
    assert set(occupied_columns) <= {14, 15}  # x in [0.45, 0.55]
    assert grid[:, 14].all() or grid[:, 15].all()


def reachable(free, start):
    """Cells of `free` 4-connected to `start` (row, column)."""
    seen = np.zeros_like(free)
    seen[start] = True
    while True:
        grown = seen.copy()
        grown[1:] |= seen[:-1]
        grown[:-1] |= seen[1:]
        grown[:, 1:] |= seen[:, :-1]
        grown[:, :-1] |= seen[:, 1:]
        grown &= free
        if (grown == seen).all():
            return seen
        seen = grown


def house_rooms_reachable(world):
    resolution, origin = 0.05, (-5.5, -4.5)
    xs = origin[0] + (np.arange(220) + 0.5) * resolution
    ys = origin[1] + (np.arange(180) + 0.5) * resolution
    grid = np.stack(np.meshgrid(xs, ys), axis=-1)
    free = ~world.contains(grid) & (world.distance_to_boundary(grid) > 0.2)

    def cell(x, y):
        return (int((y - origin[1]) / resolution), int((x - origin[0]) / resolution))
    region = reachable(free, cell(*world.spawn_pose[:2]))
    return [bool(region[cell(x, y)]) for x, y in ((-2.5, -2.5), (-1.0, 2.0), (1.5, 2.0), (2.5, -1.5))]


def test_house_rooms_are_all_reachable_and_there_is_a_loop():
    house = load_world("house")
    assert house_rooms_reachable(house) == [True] * 4
    # With any one door blocked, every room is still reachable: the doors form a loop.
    doors = [(-3.0, 0.0), (3.0, 0.0), (0.0, -2.0), (0.0, 2.0)]
    for x, y in doors:
        blocked = world_from_description({
            "spawn": list(house.spawn_pose),
            "obstacles": [{"type": "polygon", "points": ring.tolist()} for solid in house.solids for ring in solid]
            + [{"type": "circle", "center": c.tolist(), "radius": r}
               for c, r in zip(house.circle_centers, house.circle_radii)]
            + [{"type": "box", "center": [x, y], "size": [1.2, 1.2]}]})
        assert house_rooms_reachable(blocked) == [True] * 4, f"door at {(x, y)}"


def test_polygon_clearance_is_the_gap_to_the_nearest_obstacle_capped_at_the_margin():
    world = world_from_description({"obstacles": [
        {"type": "wall", "from": [1.0, -5.0], "to": [1.0, 5.0], "thickness": 0.1},
        {"type": "circle", "center": [-1.0, 0.0], "radius": 0.2}]})
    square = np.array([[-0.1, -0.1], [0.1, -0.1], [0.1, 0.1], [-0.1, 0.1]])
    assert world.polygon_clearance(square, 1.0) == pytest.approx(0.7)  # the pillar: 1.0 - 0.2 - 0.1
    assert world.polygon_clearance(square + (0.5, 0.0), 1.0) == pytest.approx(0.35)  # the wall face at 0.95
    assert world.polygon_clearance(square, 0.25) == 0.25
    assert world.polygon_clearance(square + (0.9, 0.0), 1.0) == 0.0
    assert world.polygon_boundary_touches(square + (0.9, 0.0))
    assert not world.polygon_boundary_touches(square + (0.8, 0.0))
    assert world.polygon_boundary_touches(square + (-0.75, 0.05))  # corner into the pillar
