"""The serial link to the OpenCR board, through ROBOTIS's dynamixel_sdk (Protocol 2.0, ID 200).

All packets are built and checked by the SDK; this module only decides what
to read and write, turns the SDK's result codes into exceptions, and makes the
port safe to share between the driver's threads.
"""
import threading

import dynamixel_sdk

from turtlebot3c_bringup import opencr_control_table as table
from turtlebot3c_bringup.opencr_sensors import DEVICE_INFO_SIZE, DEVICE_INFO_START, decode_device_info
from turtlebot3c_bringup.serial_errors import DEVICE_ERRORS, explain_open_error

POLL_TIMEOUT = 0.002  # s, longest single wait for reply bytes inside one SDK poll


class LinkError(Exception):
    """One request failed (timeout, corrupt reply, device error); the link may still be usable."""

    def __init__(self, message, kind):
        super().__init__(message)
        self.kind = kind  # short name for counters: "timeout", "corrupt", "device_error", ...


class LinkLost(Exception):
    """The serial device itself failed or vanished (unplugged); the port has to be reopened."""

    def __init__(self, message, fix=""):
        super().__init__(message)
        self.fix = fix  # the one thing the owner can do about it, when we know it


_RESULT_KINDS = {
    dynamixel_sdk.COMM_RX_TIMEOUT: "timeout",
    dynamixel_sdk.COMM_RX_CORRUPT: "corrupt",
    dynamixel_sdk.COMM_RX_FAIL: "rx_fail",
    dynamixel_sdk.COMM_TX_FAIL: "tx_fail",
    dynamixel_sdk.COMM_TX_ERROR: "tx_error",
    dynamixel_sdk.COMM_PORT_BUSY: "port_busy",
    dynamixel_sdk.COMM_NOT_AVAILABLE: "not_available",
}


class OpenCRLink:
    def __init__(self, port_name: str, baud_rate: int = table.BAUD_RATE, device_id: int = table.DEVICE_ID):
        self.port_name = port_name
        self.baud_rate = baud_rate
        self.device_id = device_id
        self._packets = dynamixel_sdk.PacketHandler(table.PROTOCOL_VERSION)
        self._port = None
        self._lock = threading.Lock()

    @property
    def is_open(self) -> bool:
        return self._port is not None

    def open(self):
        port = dynamixel_sdk.PortHandler(self.port_name)
        try:
            if not port.setBaudRate(self.baud_rate):
                raise LinkLost(f"baud rate {self.baud_rate} is not supported by the serial port {self.port_name}")
            # The SDK polls the port with a zero timeout while it waits for a reply: a busy loop that holds
            # the GIL and starves the node's other threads (the /cmd_vel callback among them). A short
            # blocking timeout makes each poll sleep in select until the bytes it asks for arrive.
            port.ser.timeout = POLL_TIMEOUT
        except DEVICE_ERRORS as error:
            problem = explain_open_error(self.port_name, error, "OpenCR", "opencr-port")
            raise LinkLost(problem.message, problem.fix) from error
        with self._lock:
            self._port = port

    def close(self):
        with self._lock:
            port, self._port = self._port, None
        if port is not None and port.ser is not None:
            try:
                port.ser.close()
            except DEVICE_ERRORS:
                pass

    def _call(self, what, request):
        """Run one SDK request under the lock; map failures to LinkError / LinkLost."""
        with self._lock:
            if self._port is None:
                raise LinkLost(f"{self.port_name} is not open")
            try:
                result = request(self._port)
            except DEVICE_ERRORS + (TypeError, AttributeError) as error:
                # pyserial raises on a vanished device; the SDK may then trip over a half-read reply.
                self._port.is_using = False
                raise LinkLost(f"{what} on {self.port_name}: {error}") from error
        # The SDK answers (value, comm_result, device_error) for reads and pings, (comm_result, device_error)
        # for writes.
        value, comm_result, device_error = result if len(result) == 3 else (None,) + tuple(result)
        if comm_result != dynamixel_sdk.COMM_SUCCESS:
            raise LinkError(f"{what}: {self._packets.getTxRxResult(comm_result)}",
                            _RESULT_KINDS.get(comm_result, "comm_error"))
        if device_error & ~0x80:  # bit 7 is the hardware-alert flag, not a failed request
            raise LinkError(f"{what}: the board answered {self._packets.getRxPacketError(device_error)}",
                            "device_error")
        return value

    def ping(self) -> int:
        """The model number the device at our ID reports."""
        return self._call("ping", lambda port: self._packets.ping(port, self.device_id))

    def read(self, address: int, length: int) -> bytes:
        data = self._call(f"read of {length} bytes at {address}",
                          lambda port: self._packets.readTxRx(port, self.device_id, address, length))
        if len(data) != length:
            raise LinkError(f"read of {length} bytes at {address}: got {len(data)} bytes", "short_reply")
        return bytes(data)

    def write(self, address: int, data: bytes):
        self._call(f"write of {len(data)} bytes at {address}",
                   lambda port: self._packets.writeTxRx(port, self.device_id, address, len(data), list(data)))

    def read_device_info(self):
        return decode_device_info(self.read(DEVICE_INFO_START, DEVICE_INFO_SIZE))

    def read_sensor_block(self) -> bytes:
        return self.read(table.SENSOR_BLOCK_START, table.SENSOR_BLOCK_SIZE)

    def write_velocity(self, command: bytes):
        self.write(table.CMD_VELOCITY_START, command)

    def write_heartbeat(self, counter: int):
        self.write(table.HEARTBEAT.address, table.encode(table.HEARTBEAT, counter & 0xFF))

    def write_torque(self, enabled: bool):
        self.write(table.MOTOR_TORQUE_ENABLE.address, table.encode(table.MOTOR_TORQUE_ENABLE, int(enabled)))
