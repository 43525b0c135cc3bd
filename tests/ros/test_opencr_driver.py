"""The OpenCR driver (no ROS) against the simulator's fake board on a pseudo-terminal.

The board side is the sim package's FakeOpenCR behind its PtyLink, served by a
small thread here, so faults (unplugging, corrupt replies, a foreign device)
can be switched from the test itself.
"""
import math
import struct
import threading
import time

import pytest

from testkit.recording_log import RecordingLog
from testkit.ros_harness import wait_until
from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_bringup.opencr_driver import (
    COMMAND_TIMEOUT,
    OpenCRDriver,
    saved_odometry_from_dict,
    saved_odometry_to_dict,
)
from turtlebot3c_bringup.opencr_link import OpenCRLink
from turtlebot3c_common.backoff import Backoff
from turtlebot3c_description.models import get_model
from turtlebot3c_sim import dynamixel_protocol as dxl
from turtlebot3c_sim.fake_opencr import FakeOpenCR
from turtlebot3c_sim.pty_link import PtyLink
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world


class BoardServer:
    """Serves a FakeOpenCR on a pty symlink in a thread; the simulation follows the wall clock."""

    def __init__(self, path, model="waffle_pi"):
        self.sim = Simulation(load_world("empty"), model=model, pose=(0.0, 0.0, 0.0), noise=NoiseConfig.none())
        self.board = FakeOpenCR(self.sim)
        self.link = PtyLink(path)
        self.corrupt_every = 0  # corrupt the CRC of every n-th reply (0: never)
        self.replies = 0
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._parser = dxl.PacketParser()
        self.link.plug()
        self._last = time.monotonic()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        while not self._stop.is_set():
            with self.lock:
                data = self.link.read(0.005)
                now = time.monotonic()
                self.sim.step(now - self._last)
                self._last = now
                if not self.link.plugged:
                    self._parser = dxl.PacketParser()
                    continue
                for packet in self._parser.feed(data):
                    reply = self.board.handle(packet)
                    if reply is None:
                        continue
                    self.replies += 1
                    if self.corrupt_every and self.replies % self.corrupt_every == 0:
                        reply = reply[:-1] + bytes([reply[-1] ^ 0xFF])
                    self.link.write(reply)

    def unplug(self):
        with self.lock:
            self.link.unplug()

    def replug(self):
        with self.lock:
            self.link.plug()
            self._parser = dxl.PacketParser()

    def close(self):
        self._stop.set()
        self._thread.join(2.0)
        self.link.close()


class Runner:
    """Runs driver.cycle() at 50 Hz in a thread, like the node's I/O loop, recording readings."""

    def __init__(self, driver):
        self.driver = driver
        self.readings = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self):
        while not self._stop.is_set():
            reading = self.driver.cycle()
            if reading is not None:
                self.readings.append(reading)
            time.sleep(0.02)

    def close(self):
        self._stop.set()
        self._thread.join(2.0)
        self.driver.shutdown()


@pytest.fixture
def board(tmp_path):
    server = BoardServer(tmp_path / "ttyACM0")
    yield server
    server.close()


def start_driver(board, model="waffle_pi", **options):
    log = RecordingLog()
    driver = OpenCRDriver(OpenCRLink(str(board.link.path)), get_model(model), log=log,
                          backoff=Backoff(0.05, 0.5), **options)
    return Runner(driver), log


@pytest.fixture
def running(board):
    runner, log = start_driver(board)
    wait_until(lambda: runner.driver.connected, 10, lambda: f"driver never connected: {log.lines}")
    yield runner, log
    runner.close()


def test_driver_connects_and_reads_the_board(running, board):
    runner, log = running
    wait_until(lambda: len(runner.readings) > 5, 10, "no readings")
    sensors = runner.readings[-1].sensors
    assert sensors.battery_voltage == pytest.approx(12.0)
    assert sensors.torque_enabled and sensors.device_status == 0
    assert runner.driver.device_info.model_number == table.MODEL_NUMBER
    assert any("firmware version 5" in message for _, message in log.lines)


def test_cmd_vel_moves_the_robot_and_odometry_follows(running, board):
    runner, _ = running
    start = len(runner.readings)
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline:
        runner.driver.command(0.2, 0.0)
        time.sleep(0.1)
    wait_until(lambda: board.sim.velocity[0] == 0.0, 5, "robot did not stop after the commands ended")
    time.sleep(0.2)
    with board.lock:
        true_x = board.sim.pose[0]
    odometry = runner.driver.odometry.pose
    assert true_x > 0.3
    assert odometry.x == pytest.approx(true_x, abs=0.02)
    assert abs(odometry.y) < 0.02
    assert any(reading.odometry_updated for reading in runner.readings[start:])


def test_silence_on_cmd_vel_stops_the_robot_after_the_command_timeout(running, board):
    runner, log = running
    runner.driver.command(0.1, 0.5)
    wait_until(lambda: board.board.goal_velocity == (0.1, 0.5), 5, "command never reached the board")
    sent = time.monotonic()
    wait_until(lambda: board.board.goal_velocity == (0.0, 0.0), 2, "board never got a zero command")
    assert time.monotonic() - sent < COMMAND_TIMEOUT + 0.2
    assert any("no /cmd_vel" in message for _, message in log.lines)


def test_commands_beyond_the_limits_are_clamped_before_the_wire(running, board):
    runner, _ = running
    runner.driver.command(5.0, -9.0)
    model = get_model("waffle_pi")
    wait_until(lambda: board.board.goal_velocity != (0.0, 0.0), 5, "command never reached the board")
    linear, angular = board.board.goal_velocity
    assert 0 < linear <= model.max_linear_velocity
    assert -model.max_angular_velocity <= angular < 0


def test_heartbeat_keeps_the_board_from_stopping(running, board):
    time.sleep(1.5)
    assert board.board.heartbeat_stalls == 0
    assert board.board.heartbeat_alive


def test_unplug_is_reported_and_replug_resumes_without_an_odometry_jump(running, board):
    runner, log = running
    for _ in range(10):
        runner.driver.command(0.2, 0.3)
        time.sleep(0.1)
    board.unplug()
    wait_until(lambda: any(level == "error" and "OpenCR link lost" in message for level, message in log.lines), 5,
               "the driver did not report the unplugged board")
    assert not runner.driver.connected
    count = len(runner.readings)
    pose_at_loss = runner.driver.odometry.pose
    time.sleep(0.5)
    assert len(runner.readings) == count  # nothing stale while unplugged
    # The board keeps its motion going and its encoders count on; after replug the driver must not
    # add the travel it did not see as one jump.
    board.replug()
    wait_until(lambda: runner.driver.connected, 5, lambda: f"no reconnection: {log.lines[-3:]}")
    wait_until(lambda: len(runner.readings) > count + 5, 5, "no readings after reconnection")
    pose_after = runner.driver.odometry.pose
    assert math.hypot(pose_after.x - pose_at_loss.x, pose_after.y - pose_at_loss.y) < 0.05
    assert any("restored" in message for _, message in log.lines)
    assert runner.driver.stats.link_losses == 1 and runner.driver.stats.reconnections == 1


def test_corrupt_replies_are_counted_and_survived(running, board):
    runner, _ = running
    board.corrupt_every = 5
    count = len(runner.readings)
    time.sleep(1.5)
    board.corrupt_every = 0
    assert runner.driver.stats.errors.get("corrupt", 0) > 5
    assert runner.driver.connected
    assert len(runner.readings) > count + 20


def test_a_device_that_is_not_an_opencr_is_refused_with_the_reason(board):
    with board.lock:
        struct.pack_into("<H", board.board.memory, table.MODEL_NUMBER_ITEM.address, 0x0424)
    runner, log = start_driver(board)
    try:
        wait_until(lambda: any(level == "error" for level, _ in log.lines), 5, "no error about the device")
        assert not runner.driver.connected
        message = next(message for level, message in log.lines if level == "error")
        assert "0x0424" in message and "0x5000" in message and "firmware" in message
    finally:
        runner.close()


def test_a_missing_port_is_retried_until_the_board_appears(tmp_path):
    path = tmp_path / "ttyACM9"
    log = RecordingLog()
    runner = Runner(OpenCRDriver(OpenCRLink(str(path)), get_model("burger"), log=log, backoff=Backoff(0.05, 0.3)))
    try:
        time.sleep(0.5)
        assert not runner.driver.connected
        assert any("cannot reach the OpenCR" in message for _, message in log.lines)
        server = BoardServer(path, model="burger")
        try:
            wait_until(lambda: runner.driver.connected, 5, lambda: f"never connected: {log.lines}")
        finally:
            runner.close()
            server.close()
    finally:
        runner.close()


def test_a_board_that_never_answers_gets_a_firmware_hint(tmp_path):
    silent = PtyLink(tmp_path / "ttyACM0")  # a port whose device says nothing, like the ROS 1 firmware at 1 Mbps
    silent.plug()
    log = RecordingLog()
    runner = Runner(OpenCRDriver(OpenCRLink(str(silent.path)), get_model("burger"), log=log,
                                 backoff=Backoff(0.05, 0.3)))
    try:
        wait_until(lambda: log.lines, 5, "nothing logged about the silent board")
        assert not runner.driver.connected
        level, message = log.lines[0]
        assert level == "warning"
        assert "cannot reach the OpenCR" in message and "ROS 2 TurtleBot3 firmware" in message
    finally:
        runner.close()
        silent.close()


def test_a_restarted_driver_resumes_the_odometry_of_the_one_that_died(board):
    first, _ = start_driver(board)
    wait_until(lambda: first.driver.connected and first.driver.saved_odometry is not None, 10, "no first driver")
    for _ in range(10):
        first.driver.command(0.2, 0.4)
        time.sleep(0.1)
    first._stop.set()  # dies without a goodbye: no zero command, the port just closes
    first._thread.join(2.0)
    first.driver.link.close()
    saved = first.driver.saved_odometry
    time.sleep(0.3)  # the robot coasts on while nobody watches (the board stops it after 0.5 s)
    assert saved_odometry_from_dict(saved_odometry_to_dict(saved)) == saved
    second, _ = start_driver(board, resume=saved_odometry_from_dict(saved_odometry_to_dict(saved)))
    try:
        wait_until(lambda: len(second.readings) > 3, 10, "second driver got no readings")
        wait_until(lambda: board.sim.velocity == (0.0, 0.0), 5, "robot did not stop")
        time.sleep(0.2)
        with board.lock:
            true_x, true_y, true_yaw = board.sim.pose
        pose = second.driver.odometry.pose
        # the odometry started at the sim's origin (0, 0, 0), so it must match the true pose,
        # including the travel made while no driver ran
        assert math.hypot(pose.x - true_x, pose.y - true_y) < 0.02
        assert abs(pose.yaw - true_yaw) < 0.02
        assert math.hypot(pose.x - saved.odometry.x, pose.y - saved.odometry.y) > 0.01
    finally:
        second.close()


def test_saved_odometry_that_is_not_one_is_refused():
    with pytest.raises(ValueError, match="not a saved odometry"):
        saved_odometry_from_dict({"x": 1.0})
    with pytest.raises(ValueError, match="not a saved odometry"):
        saved_odometry_from_dict("garbage")
