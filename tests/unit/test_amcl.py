"""The particle filter against the simulator: tracking, motion model, KLD, relocalisation."""
import math

import numpy as np
import pytest

from turtlebot3c_description.models import get_model
from turtlebot3c_navigation.amcl import AmclParams, ParticleFilter, kld_particle_count, params_from_dict
from turtlebot3c_navigation.grid_info import GridInfo
from turtlebot3c_navigation.navigation_stack import Localizer, make_filter, make_navigator, pose_error, scan_offset
from turtlebot3c_sim.navigation_loop import ClosedLoop, world_layers
from turtlebot3c_sim.simulation import Simulation
from turtlebot3c_sim.world import load_world


def open_grid():
    occupied = np.zeros((40, 40), bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    return occupied, GridInfo(0.1, 40, 40, 0.0, 0.0)


def test_kld_needs_more_particles_for_more_bins():
    assert kld_particle_count(1, 0.02, 2.33) == 1.0
    counts = [kld_particle_count(bins, 0.02, 2.33) for bins in (2, 10, 100, 1000)]
    assert counts == sorted(counts) and counts[-1] > 10 * counts[1]


def test_unknown_parameter_names_are_refused_with_the_known_ones_listed():
    with pytest.raises(ValueError, match="unknown amcl parameters: laser_sigma.*known: min_particles"):
        params_from_dict({"laser_sigma": 0.1})
    assert params_from_dict({"max_particles": "2000"}).max_particles == 2000


def test_a_map_without_free_space_is_refused():
    occupied, info = open_grid()
    with pytest.raises(ValueError, match="no free cell"):
        ParticleFilter(occupied, info, free=np.zeros_like(occupied))


def test_motion_model_moves_the_cloud_by_the_odometry_increment():
    occupied, info = open_grid()
    alphas = dict(odom_alpha1=0.01, odom_alpha2=0.01, odom_alpha3=0.01, odom_alpha4=0.01)
    particle_filter = ParticleFilter(occupied, info, params=AmclParams(**alphas), seed=1)
    particle_filter.set_pose((1.0, 1.0, 0.0), np.diag([1e-6, 1e-6, 1e-6]))
    particle_filter.apply_motion((5.0, 5.0, math.pi / 2), (5.0, 6.0, math.pi / 2))  # 1 m forward, odom frame
    mean = particle_filter.particles.mean(axis=0)
    assert mean[0] == pytest.approx(2.0, abs=0.02)
    assert mean[1] == pytest.approx(1.0, abs=0.02)
    assert particle_filter.particles[:, 0].std() == pytest.approx(math.sqrt(0.01), rel=0.1)  # alpha3 * trans^2
    assert particle_filter.particles[:, 1].std() == pytest.approx(math.sqrt(0.01), rel=0.1)  # rot1: alpha2 * trans^2


def test_resampling_shrinks_a_converged_cloud_to_min_particles():
    occupied, info = open_grid()
    params = AmclParams(min_particles=200, max_particles=2000)
    particle_filter = ParticleFilter(occupied, info, params=params, seed=1)
    particle_filter.set_pose((2.2, 2.2, 0.1), np.diag([1e-4, 1e-4, 1e-4]))  # inside one KLD bin
    particle_filter.resample()
    assert particle_filter.particles.shape[0] == 200
    particle_filter.global_localization()
    particle_filter.resample()
    assert particle_filter.particles.shape[0] > 1000


def drive(world_name, model_name, seed, goals, set_up, start=None):
    """Drive the robot through goals on its true pose while a shadow filter localises it."""
    world = load_world(world_name)
    if start is not None:
        world.spawn_pose = start
    layers = world_layers(world)
    model = get_model(model_name)
    sim = Simulation(world, model_name, pose=world.spawn_pose, seed=seed)
    localizer = Localizer(make_filter(layers, AmclParams(), seed=seed))
    set_up(localizer, sim)
    loop = ClosedLoop(sim, make_navigator(layers, model), None, scan_offset(model), shadow_localizer=localizer)
    errors = []
    for goal in goals:
        result = loop.run_to_goal(goal, timeout=90)
        assert result.state == "succeeded", result
        errors.append(pose_error(localizer.pose(loop.odom_pose()), sim.pose))
    return errors


def test_tracking_from_the_initial_pose_stays_within_centimetres():
    def start_at_spawn(localizer, sim):
        localizer.set_pose(sim.pose, sim.odometry[:3])
    errors = drive("turtlebot3_world", "burger", 4, [(-0.5, -1.6, 0.0), (0.55, 0.55, 1.5)], start_at_spawn)
    for position_error, heading_error in errors:
        assert position_error < 0.05 and heading_error < math.radians(3)


@pytest.mark.parametrize("world_name", ["turtlebot3_world", "house"])
def test_wrong_initial_pose_is_corrected_by_global_localization(world_name):
    def wrong_then_global(localizer, sim):
        x, y, yaw = sim.pose
        localizer.set_pose((x + 1.0, y + 0.8, yaw + 1.0), sim.odometry[:3])
        localizer.global_localization()
    goals = {"turtlebot3_world": [(-1.6, 0.55, 1.0), (0.55, 1.6, 0.0), (1.6, 0.55, -1.5)],
             "house": [(-2.5, -1.0, 1.5), (-3.0, 1.5, 0.0), (-1.0, 2.0, 0.0)]}[world_name]
    errors = drive(world_name, "burger", 2, goals, wrong_then_global)
    position_error, heading_error = errors[-1]
    assert position_error < 0.05 and heading_error < math.radians(3)


def test_a_confidently_wrong_pose_is_noticed_and_relocalised_without_being_asked():
    filters = []

    def wrong_and_sure(localizer, sim):
        x, y, yaw = sim.pose
        localizer.set_pose((x - 1.5, y - 1.0, yaw + 2.0), sim.odometry[:3], np.diag([1e-4, 1e-4, 1e-4]))
        filters.append(localizer.filter)
    # Through the house and back: from some places its rooms look alike (the filter may first
    # settle on a look-alike), and the drive must pass places that tell them apart.
    goals = [(2.5, -2.0, 1.5), (3.5, 1.0, 0.0), (-2.5, -1.0, 1.5), (2.5, 2.0, 0.0)]
    errors = drive("house", "burger", 1, goals, wrong_and_sure, start=(2.5, 2.0, 0.0))
    assert filters[0].relocalizations == 1
    position_error, heading_error = errors[-1]
    assert position_error < 0.05 and heading_error < math.radians(3)
