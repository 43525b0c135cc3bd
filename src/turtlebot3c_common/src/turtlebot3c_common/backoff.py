"""Delays between reconnection attempts."""


class Backoff:
    """Doubling from `initial` up to `maximum`; `reset()` after a success."""

    def __init__(self, initial: float = 0.1, maximum: float = 2.0):
        if not 0 < initial <= maximum:
            raise ValueError(f"need 0 < initial <= maximum, got {initial}, {maximum}")
        self.initial = initial
        self.maximum = maximum
        self._next = initial

    def next_delay(self) -> float:
        delay = self._next
        self._next = min(self.maximum, self._next * 2.0)
        return delay

    def reset(self):
        self._next = self.initial
