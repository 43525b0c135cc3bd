"""bench_slam's drive in a simulated world, for the benchmark and the tests that need its scans:
a burger follows the world's route (turtlebot3c_sim.evaluation.ROUTES) and takes a scan at
every LIDAR revolution, each with the odometry and the true pose at its time."""
from turtlebot3c_sim.evaluation import ROUTES, drive_route
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world
from turtlebot3c_slam.slam_scan import ScanGeometry


def drive(world_name, seed, noise=None):
    """(world, scans [(stamp, Scan, odometry (x, y, yaw), true pose)], the scans' ScanGeometry);
    RuntimeError when the route hits an obstacle."""
    world = load_world(world_name)
    sim = Simulation(world, model="burger", pose=world.spawn_pose, seed=seed, noise=noise or NoiseConfig())
    scans = []

    def on_scan(simulation):
        scan = simulation.scan()
        scans.append((simulation.time, scan, simulation.odometry[:3], simulation.pose))
    if not drive_route(sim, ROUTES[world_name], 0.2, on_scan, timeout=3600):
        raise RuntimeError(f"the route in {world_name} hit an obstacle")
    mount = sim.model.scan_mount
    first = scans[0][1]
    geometry = ScanGeometry(first.angle_min, first.angle_increment, len(first.ranges), first.range_min,
                            first.range_max, (mount[0], mount[1], 0.0))
    return world, scans, geometry
