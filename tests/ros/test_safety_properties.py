"""Safety properties over random runs: hypothesis drives sequences of commands, source switches and faults.

In simulated time, through the real components (the watchdog after the mux, the
OpenCR driver's clamping and its own timeout, the simulated robot's physics, the
navigation stack), then through ROS in the simulator with SIGKILLed sources.
Example counts are bounded so the suite stays fast; `benchmarks/bench_faults
--safety-examples N` runs many more.
"""
import math
import os
import struct
import xml.etree.ElementTree as ElementTree
from typing import List, NamedTuple

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from testkit.ros_harness import PRIME_ROS
from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_bringup.opencr_driver import OpenCRDriver
from turtlebot3c_bringup.opencr_sensors import EXPECTED_MODEL_INFORMATION, DeviceInfo
from turtlebot3c_description.models import get_model
from turtlebot3c_sim.navigation_loop import closed_loop
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world
from turtlebot3c_teleop.joy_teleop import JoyTeleop, config_from_params
from turtlebot3c_teleop.keyboard_teleop import KeyboardTeleop, limits_for_model
from turtlebot3c_teleop.velocity_watchdog import VelocityWatchdog

MODELS = ("burger", "waffle", "waffle_pi")
REST_BUDGET = 0.5  # s from a source's death to a robot that no longer travels
EXAMPLES = int(os.environ.get("TURTLEBOT3C_SAFETY_EXAMPLES", "25"))
STEP = 0.005  # s of simulated time per step of the chain


def launch_watchdog_timeout():
    """The watchdog timeout the teleop daemon really runs with (its launch file's default)."""
    launch = PRIME_ROS / "share/turtlebot3c_teleop/launch"
    root = ElementTree.parse(launch / "turtlebot3c_teleop.launch").getroot()
    return float(next(arg.get("default") for arg in root.iter("arg") if arg.get("name") == "watchdog_timeout"))


WATCHDOG_TIMEOUT = launch_watchdog_timeout()


# --- a robot base that records what reaches its wheels --------------------------------------


class SimulatedBoardLink:
    """OpenCRLink's interface over a Simulation: velocity writes become the simulated wheels' command."""

    port_name = "/dev/simulated"
    device_id = table.DEVICE_ID

    def __init__(self, sim: Simulation):
        self.sim = sim
        self.written: List[tuple] = []

    def open(self):
        pass

    def close(self):
        pass

    def ping(self):
        return table.MODEL_NUMBER

    def read_device_info(self):
        return DeviceInfo(table.MODEL_NUMBER, EXPECTED_MODEL_INFORMATION.get(self.sim.model.name, 0), 1)

    def read_sensor_block(self):
        return bytes(table.SENSOR_BLOCK_SIZE)

    def write_velocity(self, command: bytes):
        linear, _, _, _, _, angular = struct.unpack("<6i", command)
        velocity = (linear / table.VELOCITY_SCALE, angular / table.VELOCITY_SCALE)
        self.written.append(velocity)
        self.sim.set_command(*velocity)

    def write_heartbeat(self, counter):
        pass

    def write_torque(self, enabled):
        pass


class QuietLog:
    def info(self, message):
        pass

    warning = error = info


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def within_limits(velocity, model, tolerance=1e-9):
    linear, angular = velocity
    return (abs(linear) <= model.max_linear_velocity + tolerance
            and abs(angular) <= model.max_angular_velocity + tolerance)


finite_or_not = st.one_of(st.floats(-10.0, 10.0), st.sampled_from([math.inf, -math.inf, math.nan, 1e300, -1e300]))


@settings(max_examples=EXAMPLES * 4, deadline=None)
@given(model_name=st.sampled_from(MODELS), commands=st.lists(st.tuples(finite_or_not, finite_or_not), max_size=30))
def test_what_reaches_the_wheels_never_exceeds_the_models_limits(model_name, commands):
    model = get_model(model_name)
    sim = Simulation(load_world("empty"), model_name, noise=NoiseConfig.none())
    link = SimulatedBoardLink(sim)
    clock = Clock()
    driver = OpenCRDriver(link, model, clock=clock, log=QuietLog())
    driver.cycle()
    assert driver.connected
    for linear, angular in commands:
        clock.now += 0.02
        driver.command(linear, angular)
        driver.cycle()
    assert all(within_limits(velocity, model) for velocity in link.written), link.written


@settings(max_examples=EXAMPLES * 4, deadline=None)
@given(model_name=st.sampled_from(MODELS),
       actions=st.lists(st.one_of(st.sampled_from(list("wxads q")), st.floats(0.0, 2.0)), max_size=80))
def test_key_teleop_never_asks_for_more_than_the_models_limits(model_name, actions):
    model = get_model(model_name)
    teleop = KeyboardTeleop(limits_for_model(model))
    for action in actions:
        if isinstance(action, str):
            teleop.press(action)
        else:
            teleop.advance(action)
        assert within_limits((teleop.linear, teleop.angular), model)


@settings(max_examples=EXAMPLES * 4, deadline=None)
@given(model_name=st.sampled_from(MODELS),
       inputs=st.lists(st.tuples(st.lists(st.floats(-3.0, 3.0), min_size=0, max_size=8),
                                 st.lists(st.integers(0, 1), min_size=0, max_size=12)), max_size=40))
def test_joystick_teleop_never_asks_for_more_than_the_models_limits(model_name, inputs):
    model = get_model(model_name)
    teleop = JoyTeleop(config_from_params({}), model)
    for axes, buttons in inputs:
        velocity = teleop.update(axes, buttons).velocity
        assert velocity is None or within_limits(velocity, model)


# --- sources dying, switched away or muted, in simulated time ------------------------------


class Phase(NamedTuple):
    source: str  # the mux input selected for this phase
    linear: float  # what the source asks for (may be beyond the limits: the driver clamps)
    angular: float
    rate: float  # Hz the source publishes at
    duration: float  # s it publishes for
    ending: str  # "sigkill": the source dies; "none": the mux selects __none; "switch": the next phase's source


phases = st.builds(
    Phase, source=st.sampled_from(["nav_vel", "key_vel", "joy_vel"]), linear=st.floats(-0.5, 0.5),
    angular=st.floats(-3.0, 3.0), rate=st.floats(5.0, 20.0), duration=st.floats(0.2, 2.0),
    ending=st.sampled_from(["sigkill", "none", "switch"]))


class Chain:
    """Source -> mux -> watchdog (checked at 50 Hz) -> driver (50 Hz cycle) -> simulated robot."""

    def __init__(self, model_name, transport_delay):
        self.model = get_model(model_name)
        self.sim = Simulation(load_world("empty"), model_name, noise=NoiseConfig.none())
        self.clock = Clock()
        self.link = SimulatedBoardLink(self.sim)
        self.driver = OpenCRDriver(self.link, self.model, clock=self.clock, log=QuietLog())
        self.watchdog = VelocityWatchdog(WATCHDOG_TIMEOUT)
        self.transport_delay = transport_delay
        self.in_flight = []  # (arrival time, input, command)
        self.selected = "nav_vel"
        self.travel_after = []  # (time, position) samples
        self.driver.cycle()

    def run(self, seconds, publish=None):
        """Advance; `publish` = (input, command, period, first time) sends like a source meanwhile."""
        end = self.clock.now + seconds
        next_publish = publish[3] if publish else math.inf
        while self.clock.now < end - 1e-9:
            now = self.clock.now
            if now >= next_publish - 1e-9:
                self.in_flight.append((now + self.transport_delay, publish[0], publish[1]))
                next_publish += publish[2]
            for message in [m for m in self.in_flight if m[0] <= now + 1e-9]:
                self.in_flight.remove(message)
                if message[1] == self.selected:
                    self.watchdog.command_received(now)
                    self.driver.command(*message[2])
            if round(now / STEP) % 4 == 0:  # 50 Hz: the watchdog's check and the driver's cycle
                if self.watchdog.should_stop(now):
                    self.driver.command(0.0, 0.0)
                self.driver.cycle()
            self.sim.step(STEP)
            self.clock.now += STEP
            self.travel_after.append((self.clock.now, self.sim.pose[:2], self.sim.velocity))
        return next_publish - publish[2] if publish else None

    def travelling(self):
        return self.sim.velocity[0] != 0.0


@settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(model_name=st.sampled_from(MODELS), run=st.lists(phases, min_size=1, max_size=5),
       transport_delay=st.floats(0.0, 0.02), death_offsets=st.lists(st.floats(0.0, 1.0), min_size=5, max_size=5))
def test_the_robot_stops_travelling_within_half_a_second_of_its_source_dying_or_being_switched_off(
        model_name, run, transport_delay, death_offsets):
    chain = Chain(model_name, transport_delay)
    for phase, offset in zip(run, death_offsets):
        chain.selected = phase.source
        period = 1.0 / phase.rate
        last_sent = chain.run(phase.duration, (phase.source, (phase.linear, phase.angular), period, chain.clock.now))
        if phase.ending == "switch":
            continue
        # A SIGKILL lands anywhere between the last message and the one that would have come next.
        dies_at = last_sent + offset * period if phase.ending == "sigkill" else chain.clock.now
        if phase.ending == "none":
            chain.selected = "__none"
        chain.run(max(0.0, dies_at - chain.clock.now))
        chain.travel_after.clear()
        chain.run(REST_BUDGET)
        assert not chain.travelling(), f"travelling {REST_BUDGET} s after the source stopped: {chain.sim.velocity}"
        position = chain.sim.pose[:2]
        chain.run(0.5)
        assert chain.sim.pose[:2] == position, "the robot travelled again with no source"
        # Turning in place is slowed by the model's angular deceleration limit: it ends, too.
        chain.run(1.5)
        assert chain.sim.velocity == (0.0, 0.0)
    assert all(within_limits(velocity, chain.model) for velocity in chain.link.written)


# --- navigation -----------------------------------------------------------------------------


def open_places(world_name="turtlebot3_world", clearance=0.3, reach=2.0, spacing=0.25):
    """Points inside the world's outer wall with room for the robot: goals worth driving to."""
    world = load_world(world_name)
    steps = int(reach / spacing)
    points = [(i * spacing, j * spacing) for i in range(-steps, steps + 1) for j in range(-steps, steps + 1)]
    return [(x, y) for x, y in points if math.hypot(x, y) <= reach and not world.collides(x, y, clearance)]


OPEN_PLACES = open_places()


@settings(max_examples=max(2, EXAMPLES // 8), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(model_name=st.sampled_from(MODELS), seed=st.integers(0, 1000),
       goals=st.lists(st.tuples(st.sampled_from(OPEN_PLACES), st.floats(-math.pi, math.pi)), min_size=1, max_size=2))
def test_navigating_to_random_goals_never_collides_and_stays_within_the_limits(model_name, seed, goals):
    loop = closed_loop(model_name=model_name, seed=seed)
    commands = []
    set_command = loop.sim.set_command

    def recorded(linear, angular):
        commands.append((linear, angular))
        set_command(linear, angular)
    loop.sim.set_command = recorded
    for (x, y), yaw in goals:
        result = loop.run_to_goal((x, y, yaw), timeout=60)
        assert not result.collided, ((x, y, yaw), result)
    assert loop.sim.collisions == 0
    assert all(within_limits(command, loop.sim.model) for command in commands)
