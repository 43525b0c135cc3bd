"""Decide when a velocity stream has gone stale and the robot must be stopped.

The mux forwards whatever its selected source publishes and nothing when that
source dies, so the last command would stay in force. The watchdog sits after
the mux: every command passes straight through, and once no command has
arrived for `timeout` seconds it asks for a single zero command.
"""


class VelocityWatchdog:
    def __init__(self, timeout: float):
        if timeout <= 0:
            raise ValueError(f"watchdog timeout must be positive, got {timeout}")
        self.timeout = timeout
        self._last_command_time = None
        self._stopped = True

    def command_received(self, now: float) -> None:
        self._last_command_time = now
        self._stopped = False

    def should_stop(self, now: float) -> bool:
        """True once per stale period: when the caller must publish a zero command."""
        if self._stopped or self._last_command_time is None:
            return False
        if now - self._last_command_time < self.timeout:
            return False
        self._stopped = True
        return True
