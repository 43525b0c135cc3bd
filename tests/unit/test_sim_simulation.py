"""Kinematic simulation against closed forms: straight line, spin, arc; contact; sensors; determinism."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from turtlebot3c_description.models import get_model
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world, world_from_description

EMPTY = load_world("empty")


def run(sim, seconds, dt=0.01):
    for _ in range(int(round(seconds / dt))):
        sim.step(dt)


def perfect(model="burger", pose=(0.0, 0.0, 0.0), world=EMPTY):
    return Simulation(world, model=model, pose=pose, seed=0, noise=NoiseConfig.none())


@pytest.mark.parametrize("model", ["burger", "waffle_pi"])
def test_straight_line_from_rest_matches_constant_acceleration_then_cruise(model):
    sim = perfect(model)
    limits = get_model(model)
    speed = 0.2
    sim.set_command(speed, 0.0)
    run(sim, 3.0)
    expected = speed * 3.0 - speed ** 2 / (2 * limits.max_linear_acceleration)
    x, y, yaw = sim.pose
    assert x == pytest.approx(expected, abs=1e-9)
    assert y == pytest.approx(0.0, abs=1e-12) and yaw == pytest.approx(0.0, abs=1e-12)
    assert sim.velocity == pytest.approx((speed, 0.0))
    assert sim.time == pytest.approx(3.0)


def test_spin_in_place_matches_constant_angular_acceleration_then_cruise():
    sim = perfect("burger")
    sim.set_command(0.0, 1.0)
    run(sim, 2.0)
    expected = 1.0 * 2.0 - 1.0 / (2 * get_model("burger").max_angular_acceleration)
    assert sim.pose[2] == pytest.approx(expected, abs=1e-9)
    assert sim.pose[:2] == pytest.approx((0.0, 0.0), abs=1e-12)


def test_arc_at_steady_speed_follows_the_circle_of_radius_v_over_w():
    sim = perfect("waffle")
    v, w = 0.2, 0.5
    sim.set_command(v, w)
    run(sim, 1.0)
    x0, y0, yaw0 = sim.pose
    center = (x0 - v / w * math.sin(yaw0), y0 + v / w * math.cos(yaw0))
    run(sim, 4.0, dt=0.05)
    x, y, yaw = sim.pose
    assert math.hypot(x - center[0], y - center[1]) == pytest.approx(v / w, abs=1e-9)
    assert math.remainder(yaw - (yaw0 + w * 4.0), 2 * math.pi) == pytest.approx(0.0, abs=1e-9)


def test_one_long_step_agrees_with_many_short_ones():
    coarse, fine = perfect(), perfect()
    for sim in (coarse, fine):
        sim.set_command(0.15, -0.8)
    coarse.step(2.0)
    run(fine, 2.0, dt=0.001)
    assert coarse.pose == pytest.approx(fine.pose, abs=1e-3)


def test_commands_are_clamped_to_the_model_limits():
    sim = perfect("burger")
    sim.set_command(5.0, -50.0)
    limits = get_model("burger")
    assert sim.command == pytest.approx((limits.max_linear_velocity, -limits.max_angular_velocity))
    sim.set_command(float("nan"), float("inf"))
    assert sim.command == (0.0, 0.0)


def test_the_simulation_records_when_the_command_last_changed():
    # What the fault tests time a stop from: a status poll on a loaded machine comes later.
    sim = perfect("burger")
    run(sim, 0.5)
    sim.set_command(0.1, 0.0)
    run(sim, 1.0)
    sim.set_command(0.1, 0.0)  # the same command again, as the driver writes it every cycle
    assert sim.command_since == pytest.approx(0.5)
    run(sim, 0.25)
    sim.stop()
    run(sim, 1.0)
    assert sim.command_since == pytest.approx(1.75)


def test_the_robot_stops_at_a_wall_and_reports_the_contact():
    world = world_from_description({"obstacles": [{"type": "wall", "from": [1.0, -5], "to": [1.0, 5]}]})
    sim = perfect("burger", world=world)
    sim.set_command(0.2, 0.0)
    run(sim, 10.0)
    front = sim.pose[0] + max(x for x, _ in get_model("burger").footprint)
    assert front == pytest.approx(0.95, abs=0.005)
    assert front < 0.95
    assert sim.collided and sim.in_contact and sim.collisions == 1
    assert sim.velocity == (0.0, 0.0)
    assert not world.polygon_collides(sim.footprint_at(*sim.pose))
    sim.set_command(-0.2, 0.0)
    run(sim, 2.0)
    assert sim.pose[0] < 0.6 and not sim.in_contact and sim.collided
    sim.clear_collision()
    assert not sim.collided


def test_start_pose_inside_an_obstacle_is_refused():
    with pytest.raises(ValueError, match="overlaps an obstacle"):
        Simulation(load_world("turtlebot3_world"), pose=(0.0, 0.0, 0.0))


def test_perfect_odometry_wheels_and_imu_follow_the_truth():
    sim = perfect("burger", pose=(1.0, 2.0, 0.5))
    for command in ((0.2, 0.0), (0.1, 1.0), (0.0, -2.0), (-0.1, 0.3)):
        sim.set_command(*command)
        run(sim, 1.5)
    x, y, yaw, linear, angular = sim.odometry
    assert (x, y, yaw) == pytest.approx(sim.pose, abs=1e-9)
    assert (linear, angular) == pytest.approx(sim.velocity, abs=1e-9)
    assert sim.imu().orientation_yaw == pytest.approx(sim.pose[2], abs=1e-9)


def test_wheels_turn_by_distance_over_radius():
    sim = perfect("waffle")
    sim.set_command(0.2, 0.0)
    run(sim, 2.0)
    assert sim.wheel_positions == pytest.approx((sim.pose[0] / 0.033,) * 2)
    sim = perfect("burger")
    sim.set_command(0.0, 1.0)
    run(sim, 2.0)
    left, right = sim.wheel_positions
    assert right == pytest.approx(-left) and right == pytest.approx(sim.pose[2] * 0.080 / 0.033)


def test_imu_sees_centripetal_acceleration_and_gravity():
    sim = perfect("burger")
    sim.set_command(0.2, 1.0)
    run(sim, 2.0)
    imu = sim.imu()
    assert imu.angular_velocity_z == pytest.approx(1.0)
    assert imu.linear_acceleration_x == pytest.approx(0.0)
    assert imu.linear_acceleration_y == pytest.approx(0.2)
    assert imu.linear_acceleration_z == pytest.approx(9.80665)
    w, qx, qy, qz = imu.orientation_quaternion
    assert 2 * math.atan2(qz, w) == pytest.approx(sim.pose[2]) and qx == qy == 0.0


def drive_square(sim):
    for _ in range(4):
        sim.set_command(0.2, 0.0)
        run(sim, 5.0)
        sim.set_command(0.0, 1.0)
        run(sim, math.pi / 2)


def test_noisy_odometry_drifts_from_the_truth_but_stays_plausible():
    sim = Simulation(EMPTY, pose=(0.0, 0.0, 0.0), seed=3)
    drive_square(sim)
    x, y, yaw, _, _ = sim.odometry
    error = math.hypot(x - sim.pose[0], y - sim.pose[1])
    assert 1e-4 < error < 0.3
    assert sum(sim.wheel_positions) / 2 * 0.033 > 4 * 5.0 * 0.2 * 0.9


def test_same_seed_same_run_and_different_seed_different_run():
    def record(seed):
        sim = Simulation(load_world("turtlebot3_world"), model="waffle_pi", seed=seed)
        scans = []
        for command in ((0.2, 0.3), (0.1, -0.5), (0.25, 0.0)):
            sim.set_command(*command)
            run(sim, 1.0)
            scans.append(sim.scan().ranges)
        return sim.pose, sim.odometry, sim.imu(), np.array(scans)
    first, again, other = record(7), record(7), record(8)
    assert first[0] == again[0] and first[1] == again[1] and first[2] == again[2]
    assert np.array_equal(first[3], again[3])
    assert first[1] != other[1]
    assert not np.array_equal(first[3], other[3])


def test_taking_scans_does_not_change_the_motion():
    quiet, busy = (Simulation(EMPTY, seed=1) for _ in range(2))
    for sim in (quiet, busy):
        sim.set_command(0.2, 0.4)
    for _ in range(100):
        quiet.step(0.02)
        busy.step(0.02)
        busy.scan()
        busy.imu()
    assert quiet.odometry == busy.odometry


def test_scan_sees_a_pillar_straight_ahead_from_the_scan_mount():
    sim = perfect("burger", pose=(-1.1, -0.6, math.pi / 2), world=load_world("turtlebot3_world"))
    scan = sim.scan()
    assert len(scan.ranges) == 360 and scan.angle_min == 0.0
    assert scan.angle_increment == pytest.approx(2 * math.pi / 360)
    assert (scan.range_min, scan.range_max) == (0.12, 3.5)
    mount_x = get_model("burger").scan_mount[0]
    assert scan.ranges[0] == pytest.approx(0.6 - mount_x - 0.15)


def test_scan_beams_go_counter_clockwise_in_the_robot_frame():
    world = world_from_description({"bounds": [-5, -5, 5, 5], "obstacles": [
        {"type": "wall", "from": [-5, 1.0], "to": [5, 1.0], "thickness": 0.1},
        {"type": "circle", "center": [-1.0, 0.0], "radius": 0.2}]})
    sim = perfect("waffle", pose=(0.0, 0.0, math.pi / 2), world=world)
    scan = sim.scan()
    mount_x = get_model("waffle").scan_mount[0]
    # Facing +y: the wall is ahead (beam 0); beam 90 looks left (-x) at the pillar, 270 right at nothing.
    angles = scan.angles[:40]
    assert np.allclose(scan.ranges[:40], (0.95 - mount_x) / np.cos(angles))
    sensor_y = mount_x  # the mount is mount_x along the heading, +y
    assert scan.ranges[90] == pytest.approx(1.0 - math.sqrt(0.2 ** 2 - sensor_y ** 2))
    assert np.isinf(scan.ranges[270]) and np.isinf(scan.ranges[180])


def test_scan_noise_has_the_configured_spread():
    world = world_from_description({"obstacles": [{"type": "ring", "outer": {
        "type": "regular_polygon", "center": [0, 0], "sides": 8, "circumradius": 1.7}, "inner": {
        "type": "regular_polygon", "center": [0, 0], "sides": 8, "circumradius": 1.5}}]})
    sim = Simulation(world, pose=(0.0, 0.0, 0.0), seed=5, noise=NoiseConfig(scan_range_std=0.01))
    truth = perfect(pose=(0.0, 0.0, 0.0), world=world).scan().ranges
    errors = np.concatenate([sim.scan().ranges - truth for _ in range(20)])
    assert abs(errors.mean()) < 0.002
    assert errors.std() == pytest.approx(0.01, rel=0.1)


# Start poses a few centimetres to decimetres from a pillar, the wall ring and a hexagon.
NEAR_OBSTACLES = [(-0.6, -1.1, math.pi), (-2.3, -0.5, 2.5), (-1.6, -1.7, -2.0)]


@settings(max_examples=20, deadline=None)
@given(st.lists(st.tuples(st.floats(-0.3, 0.3), st.floats(-2.0, 2.0), st.floats(0.05, 2.0)), min_size=1, max_size=8),
       st.sampled_from(["burger", "waffle"]), st.sampled_from(NEAR_OBSTACLES))
def test_no_command_sequence_drives_the_footprint_into_an_obstacle(commands, model, start):
    world = load_world("turtlebot3_world")
    sim = Simulation(world, model=model, pose=start, seed=0)
    for linear, angular, seconds in commands:
        sim.set_command(linear, angular)
        for _ in range(int(seconds / 0.05)):
            sim.step(0.05)
            assert not world.polygon_collides(sim.footprint_at(*sim.pose))
