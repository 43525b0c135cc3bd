"""The stop after a source dies, through ROS in the simulator, over random sources, speeds and rates.

The same property as test_safety_properties.py's simulated-time chain, here with
the real teleop launch (mux and watchdog), the simulator node and a source
process SIGKILLed at a random moment. A few examples only: each takes seconds;
`benchmarks/bench_faults` measures the latency many times on the real-robot path.
"""
import math
import random
import signal
import time

import pytest
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st

from turtlebot3c_description.models import get_model

TWIST = "geometry_msgs/Twist"
TRUTH = "nav_msgs/Odometry"
MODEL = "burger"
REST_BUDGET = 0.5
LOAD_MARGIN = 0.2  # what a loaded test machine may add; benchmarks/bench_faults prints the real figures


@pytest.fixture(scope="module")
def simulated(ros_master):
    ros_master.launch("turtlebot3c_teleop", "turtlebot3c_teleop.launch")
    ros_master.launch("turtlebot3c_sim", "turtlebot3_world.launch", "world:=empty", "noise:=none", f"model:={MODEL}")
    ros_master.wait_for_service("/mux/select", timeout=60)
    ros_master.wait_for_publisher("/sim/ground_truth", timeout=60)
    ros_master.probe.subscribe("/sim/ground_truth", TRUTH)
    return ros_master


def travelling(message):
    return message["twist"]["twist"]["linear"]["x"] != 0.0


# No shrinking: each example is seconds of ROS, and a shrink reruns dozens; a failure is reported as drawn.
@settings(max_examples=3, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate],
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(source=st.sampled_from(["nav_vel", "key_vel", "joy_vel"]), linear=st.floats(0.05, 0.3),
       angular=st.floats(-1.0, 1.0), rate=st.sampled_from([5, 10, 20]), seed=st.integers(0, 1000))
@example(source="nav_vel", linear=0.05, angular=1e-05, rate=5, seed=0)  # str() writes 1e-05: once sent as a string
def test_the_simulated_robot_stops_travelling_within_half_a_second_of_a_random_source_being_sigkilled(
        simulated, source, linear, angular, rate, seed):
    probe = simulated.probe
    direction = random.Random(seed).choice([-1.0, 1.0])  # back and forth: the robot stays near its start
    speed = math.copysign(min(linear, get_model(MODEL).max_linear_velocity), direction)
    probe.call("/mux/select", {"topic": source})
    # Fixed-point: rostopic reads YAML 1.1, where a float written like 1e-05 is a string.
    process = simulated.start(["rostopic", "pub", "-r", str(rate), f"/{source}", TWIST,
                               f"{{linear: {{x: {speed:.6f}}}, angular: {{z: {angular:.6f}}}}}"],
                              name=f"{source}_source")
    probe.wait_for_message("/sim/ground_truth", TRUTH, timeout=30,
                           where=lambda m: m["twist"]["twist"]["linear"]["x"] == pytest.approx(speed, abs=1e-3))
    time.sleep(random.Random(seed).uniform(0.0, 1.0 / rate))  # anywhere between two of its messages
    start = probe.count("/sim/ground_truth")
    killed_at = time.time()
    process.signal(signal.SIGKILL)
    process.wait(10)
    probe.wait_for_message("/sim/ground_truth", TRUTH, start=start, timeout=5, where=lambda m: not travelling(m))
    truth = probe.timed_messages("/sim/ground_truth", start)
    # The simulator's own stamp (wall time here): when the probe received it, a loaded machine adds its delays.
    stopped_at = next(entry["msg"]["header"]["stamp"] for entry in truth if not travelling(entry["msg"]))
    print(f"{source} at {rate} Hz SIGKILLed: the robot stopped travelling after {stopped_at - killed_at:.3f} s")
    assert stopped_at - killed_at <= REST_BUDGET + LOAD_MARGIN
    time.sleep(0.5)
    assert not any(travelling(message) for message in probe.messages("/sim/ground_truth", start)[len(truth):]), \
        "the robot travelled again with its source dead"
