"""The fake OpenCR board: Dynamixel 2.0 packets, its control table, and dynamixel_sdk talking to it over a pty."""
import math
import struct
import termios
import threading
import time

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, GroupSyncRead, PacketHandler, PortHandler
from serial import SerialException

from testkit import ros_harness
from testkit.ros_harness import wait_until
from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_sim import dynamixel_protocol as dxl
from turtlebot3c_sim.fake_opencr import FakeOpenCR
from turtlebot3c_sim.fake_robot import send_command
from turtlebot3c_sim.simulation import NoiseConfig, Simulation
from turtlebot3c_sim.world import load_world

# --- packets -------------------------------------------------------------------------


def test_crc_matches_the_protocol_examples():
    assert dxl.packet(1, dxl.PING) == bytes.fromhex("FFFFFD00010300 01 194E".replace(" ", ""))
    read_block = dxl.packet(200, dxl.READ, struct.pack("<HH", 10, 172))
    assert read_block == bytes.fromhex("FFFFFD00C8070002 0A00AC00 B62F".replace(" ", ""))


def test_parser_skips_noise_and_bad_crc_and_unstuffs():
    good = dxl.packet(200, dxl.WRITE, b"\x13\x00\xff\xff\xfd\x07")
    assert b"\xff\xff\xfd\xfd" in good  # stuffed on the wire
    corrupt = bytearray(dxl.packet(200, dxl.PING))
    corrupt[-1] ^= 1
    parser = dxl.PacketParser()
    packets = parser.feed(b"\x00\xfe\xff" + bytes(corrupt) + b"\xff\xff" + good[:5])
    assert packets == [] and parser.crc_errors == 1
    packets = parser.feed(good[5:] + dxl.packet(200, dxl.PING))
    assert [p.instruction for p in packets] == [dxl.WRITE, dxl.PING]
    assert packets[0].params == b"\x13\x00\xff\xff\xfd\x07"


# --- the board without a wire -----------------------------------------------------------

def board(model="burger"):
    sim = Simulation(load_world("empty"), model=model, seed=0, noise=NoiseConfig.none())
    return FakeOpenCR(sim), sim


def request(opencr, instruction, params=b""):
    reply = opencr.handle(dxl.Packet(table.DEVICE_ID, instruction, params))
    [status] = dxl.PacketParser().feed(reply)
    return status.params[0], status.params[1:]


def write(opencr, item_or_address, data):
    address = getattr(item_or_address, "address", item_or_address)
    return request(opencr, dxl.WRITE, struct.pack("<H", address) + data)[0]


def advance(sim, opencr, seconds, heartbeat=False):
    for step in range(int(round(seconds / 0.02))):
        if heartbeat and step % 5 == 0:
            write(opencr, table.HEARTBEAT, bytes([(opencr.memory[table.HEARTBEAT.address] + 1) % 256]))
        sim.step(0.02)
        opencr.update()


def test_velocity_command_drives_the_robot_while_the_heartbeat_changes():
    opencr, sim = board()
    write(opencr, table.HEARTBEAT, b"\x01")
    assert write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(0.1, 0.5)) == dxl.ERROR_NONE
    advance(sim, opencr, 2.0, heartbeat=True)
    assert sim.velocity == pytest.approx((0.1, 0.5))


def test_heartbeat_silence_of_half_a_second_zeroes_the_goal():
    opencr, sim = board()
    write(opencr, table.HEARTBEAT, b"\x01")
    write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(0.1, 0.0))
    advance(sim, opencr, 0.46)
    assert sim.command == (0.1, 0.0)
    advance(sim, opencr, 0.06)
    assert sim.command == (0.0, 0.0) and opencr.heartbeat_stalls == 1
    write(opencr, table.HEARTBEAT, b"\x02")  # the heartbeat returning does not restart the motors
    advance(sim, opencr, 0.1)
    assert sim.command == (0.0, 0.0)


def wheel_speeds(command, model):
    linear, angular = command
    return linear - angular * model.wheel_separation / 2.0, linear + angular * model.wheel_separation / 2.0


WHEEL_LIMIT = 2.0 * math.pi * 0.033 * 337 * 0.229 / 60.0  # m/s: Goal_Velocity 337 units of 0.229 rpm


def test_velocity_commands_are_clamped_to_the_model_then_each_wheel_to_its_limit():
    opencr, sim = board("waffle")
    write(opencr, table.HEARTBEAT, b"\x01")
    write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(3.0, -9.0))
    # Clamped to the model: full speed and a full turn: the outer wheel would need twice its top speed, so it runs at
    # its limit and the inner one stands; the robot pivots on it at half speed.
    left, right = wheel_speeds(sim.command, sim.model)
    assert left == pytest.approx(WHEEL_LIMIT) and right == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("model, command", [("waffle_pi", (0.26, 0.0)), ("waffle_pi", (0.0, 1.8)),
                                            ("burger", (0.21, 0.0)), ("burger", (0.0, -2.6)),
                                            ("burger", (0.1, 1.0))])
def test_commands_every_wheel_can_follow_reach_the_robot_unchanged(model, command):
    opencr, sim = board(model)
    write(opencr, table.HEARTBEAT, b"\x01")
    write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(*command))
    assert sim.command == pytest.approx(command)


def test_driving_at_full_speed_leaves_no_room_to_turn_and_the_curve_flattens():
    opencr, sim = board("waffle_pi")
    write(opencr, table.HEARTBEAT, b"\x01")
    write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(0.26, 0.5))
    linear, angular = sim.command
    assert max(wheel_speeds(sim.command, sim.model)) == pytest.approx(WHEEL_LIMIT)
    assert linear < 0.26 and 0.0 < angular < 0.5


def test_read_only_items_and_out_of_range_requests_are_refused_unchanged():
    opencr, _ = board()
    before = bytes(opencr.memory)
    assert write(opencr, table.MILLIS, b"\x00\x00\x00\x00") == dxl.ERROR_ACCESS
    assert write(opencr, table.DEVICE_STATUS, b"\x05\x06") == dxl.ERROR_ACCESS  # 18 read-only, 19 writable
    assert write(opencr, table.MODEL_INFORMATION, b"\x03\x00\x00\x00") == dxl.ERROR_ACCESS
    assert write(opencr, table.TABLE_SIZE - 1, b"\x00\x00") == dxl.ERROR_DATA_RANGE
    assert request(opencr, dxl.READ, struct.pack("<HH", 180, 4))[0] == dxl.ERROR_DATA_RANGE
    assert request(opencr, 0x42)[0] == dxl.ERROR_INSTRUCTION
    assert bytes(opencr.memory)[:10] == before[:10]


def test_model_information_tells_burger_from_waffle():
    assert board("burger")[0].get(table.MODEL_INFORMATION) == table.MODEL_INFORMATION_BURGER
    assert board("waffle_pi")[0].get(table.MODEL_INFORMATION) == table.MODEL_INFORMATION_WAFFLE


def test_torque_off_stops_the_wheels_and_ignores_commands():
    opencr, sim = board()
    write(opencr, table.HEARTBEAT, b"\x01")
    write(opencr, table.MOTOR_TORQUE_ENABLE, b"\x00")
    write(opencr, table.CMD_VELOCITY_START, table.encode_velocity_command(0.1, 0.0))
    advance(sim, opencr, 0.3, heartbeat=True)
    assert sim.velocity == (0.0, 0.0)
    write(opencr, table.MOTOR_TORQUE_ENABLE, b"\x01")
    advance(sim, opencr, 0.3, heartbeat=True)
    assert sim.velocity[0] == pytest.approx(0.1)


# --- dynamixel_sdk over the pty -----------------------------------------------------

class Host:
    """dynamixel_sdk on the fake board's port, shared by the test and a heartbeat thread."""

    def __init__(self, path):
        self.port = PortHandler(str(path))
        assert self.port.openPort() and self.port.setBaudRate(table.BAUD_RATE)
        self.packets = PacketHandler(table.PROTOCOL_VERSION)
        self.lock = threading.Lock()
        self._beating = None

    def call_once(self, name, *args):
        with self.lock:
            return getattr(self.packets, name)(self.port, table.DEVICE_ID, *args)

    def call(self, name, *args):
        """As a driver would: a request that timed out (a busy machine can miss the SDK's ~35 ms) is retried."""
        for _ in range(3):
            answer = self.call_once(name, *args)
            result = answer[-2] if len(answer) == 3 else answer[0]
            if result != COMM_RX_TIMEOUT:
                break
        return answer

    def write(self, item, data):
        return self.call("writeTxRx", item.address, len(data), list(data))

    def beat(self):
        stop = threading.Event()

        def run(count=0):
            while not stop.wait(0.1):
                count = (count + 1) % 256
                self.call("write1ByteTxRx", table.HEARTBEAT.address, count)
        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        self._beating = (stop, thread)

    def stop_beating(self):
        stop, thread = self._beating
        stop.set()
        thread.join()

    def close(self):
        if self._beating:
            self.stop_beating()
        self.port.closePort()


class RemoteRobot:
    """fake_robot from the install space in a process of its own (no GIL shared with the SDK), on its socket."""

    def __init__(self, env, workdir):
        self.opencr_link, self.socket = workdir / "ttyACM0", workdir / "control"
        self.process = ros_harness.Process(
            ["rosrun", "turtlebot3c_sim", "fake_robot", "--opencr-link", self.opencr_link, "--world", "empty",
             "--model", "burger", "--noise", "none", "--x", "0", "--y", "0", "--control-socket", self.socket],
            env, workdir / "fake_robot.log")
        wait_until(lambda: "ready" in self.process.log_text() or not self.process.running(), 30,
                   lambda: f"fake_robot did not start:\n{self.process.log_text()}")

    def command(self, line):
        return send_command(self.socket, line)

    def snapshot(self):
        return self.command("status")

    def status(self, device="opencr"):
        return self.snapshot()["devices"][device]


@pytest.fixture
def robot(ros_env, tmp_path):
    robot = RemoteRobot(ros_env, tmp_path)
    yield robot
    robot.process.stop()


@pytest.fixture
def host(robot):
    host = Host(robot.opencr_link)
    yield host
    host.close()


def test_ping_answers_the_opencr_model_number(host):
    model_number, result, error = host.call("ping")
    assert (model_number, result, error) == (0x5000, COMM_SUCCESS, 0)


def test_sensor_block_reads_in_one_request_and_decodes(host, robot):
    data, result, error = host.call("readTxRx", table.SENSOR_BLOCK_START, table.SENSOR_BLOCK_SIZE)
    assert (result, error, len(data)) == (COMM_SUCCESS, 0, 172)
    block = bytes(data)
    assert table.decode(table.BATTERY_VOLTAGE, block) == 1200
    assert table.decode(table.IMU_ORIENTATION_W, block) == pytest.approx(1.0)
    assert table.decode(table.IMU_LINEAR_ACCELERATION_Z, block) == pytest.approx(9.80665, rel=1e-6)
    assert table.decode(table.MOTOR_TORQUE_ENABLE, block) == 1
    first_millis = table.decode(table.MILLIS, block)
    wait_until(lambda: table.decode(table.MILLIS, bytes(host.call("readTxRx", 10, 172)[0])) > first_millis + 50,
               10, "millis does not advance")


def test_velocity_command_over_the_wire_moves_the_robot_and_the_encoders(host, robot):
    host.beat()
    result, error = host.write(table.CMD_VELOCITY_LINEAR_X, table.encode_velocity_command(0.2, 0.0))
    assert (result, error) == (COMM_SUCCESS, 0)
    wait_until(lambda: robot.snapshot()["pose"][0] > 0.1, 10, "the robot did not move")
    block = bytes(host.call("readTxRx", table.SENSOR_BLOCK_START, table.SENSOR_BLOCK_SIZE)[0])
    left, right = table.decode(table.PRESENT_POSITION_LEFT, block), table.decode(table.PRESENT_POSITION_RIGHT, block)
    travelled = robot.snapshot()["pose"][0]
    assert left == right and left * table.TICK_TO_RAD * 0.033 == pytest.approx(travelled, abs=0.03)
    rpm = table.decode(table.PRESENT_VELOCITY_LEFT, block) * table.VELOCITY_UNIT_RPM
    assert rpm * 2 * math.pi / 60 * 0.033 == pytest.approx(0.2, abs=0.005)


def test_heartbeat_stall_over_the_wire_stops_the_robot(host, robot):
    host.beat()
    host.write(table.CMD_VELOCITY_LINEAR_X, table.encode_velocity_command(0.2, 0.0))
    wait_until(lambda: robot.snapshot()["velocity"][0] > 0.15, 10, "the robot did not start")
    host.stop_beating()
    wait_until(lambda: robot.snapshot()["velocity"] == [0.0, 0.0], 10, "the robot kept going without heartbeat")
    assert robot.status()["heartbeat_stalls"] == 1


def test_every_register_the_driver_writes_is_accepted(host, robot):
    assert host.call("write1ByteTxRx", table.HEARTBEAT.address, 7) == (COMM_SUCCESS, 0)
    assert host.call("write1ByteTxRx", table.MOTOR_TORQUE_ENABLE.address, 0) == (COMM_SUCCESS, 0)
    assert host.call("read1ByteTxRx", table.MOTOR_TORQUE_ENABLE.address) == (0, COMM_SUCCESS, 0)
    assert host.call("write1ByteTxRx", table.IMU_RE_CALIBRATION.address, 1) == (COMM_SUCCESS, 0)
    assert host.call("read1ByteTxRx", table.IMU_RE_CALIBRATION.address) == (0, COMM_SUCCESS, 0)
    assert host.call("write1ByteTxRx", table.SOUND.address, 3) == (COMM_SUCCESS, 0)
    profile = struct.pack("<II", 100, 100)
    assert host.write(table.PROFILE_ACCELERATION_LEFT, profile) == (COMM_SUCCESS, 0)
    status = robot.status()
    assert status["sounds"] == [3] and status["calibrations"] == 1 and status["torque"] is False
    assert host.call("write4ByteTxRx", table.MILLIS.address, 0)[1] == dxl.ERROR_ACCESS


def test_sync_read_of_the_board_works(host):
    group = GroupSyncRead(host.port, host.packets, table.BATTERY_VOLTAGE.address, 8)
    assert group.addParam(table.DEVICE_ID)
    with host.lock:
        assert group.txRxPacket() == COMM_SUCCESS
    assert group.getData(table.DEVICE_ID, table.BATTERY_VOLTAGE.address, 4) == 1200
    assert group.getData(table.DEVICE_ID, table.BATTERY_PERCENTAGE.address, 4) == 8333


@pytest.mark.parametrize("fault", ["crc", "truncate", "drop", "delay"])
def test_reply_faults_surface_as_communication_errors_and_clear(host, robot, fault):
    robot.command(f"faults opencr {fault}=1.0")
    started = time.monotonic()
    data, result, _ = host.call_once("readTxRx", table.SENSOR_BLOCK_START, table.SENSOR_BLOCK_SIZE)
    assert result != COMM_SUCCESS
    assert time.monotonic() - started < 5.0, "the SDK hung on a faulty reply"
    assert robot.status()["faults_injected"][fault] >= 1
    robot.command("faults opencr none")
    # A delayed reply may still arrive late; the SDK flushes stale input before each request.
    wait_until(lambda: host.call("ping")[1] == COMM_SUCCESS, 10, "no good reply after the faults were cleared")


def test_garbage_before_replies_is_skipped_by_the_sdk(host, robot):
    robot.command("faults opencr garbage=1.0")
    results = [host.call_once("ping")[1] for _ in range(20)]
    assert results.count(COMM_SUCCESS) >= 15  # random garbage can, rarely, look like a header
    assert robot.status()["faults_injected"]["garbage"] == 20


def test_unplug_removes_the_port_and_replug_brings_a_working_board_back(host, robot):
    link = robot.opencr_link
    robot.command("unplug opencr")
    assert not link.exists()
    # The SDK's clearPort (tcflush) or read reports the vanished device: termios.error or SerialException.
    with pytest.raises((SerialException, OSError, termios.error)):
        for _ in range(3):
            data, result, _ = host.call("readTxRx", 10, 172)
            assert result == COMM_SUCCESS
    robot.command("replug opencr")
    assert link.exists()
    again = Host(link)
    try:
        assert again.call("ping")[:2] == (0x5000, COMM_SUCCESS)
    finally:
        again.close()
    assert robot.status()["plugs"] == 2
