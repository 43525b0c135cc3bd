"""Fault injection settings for the fake devices, parsed from `key=value,key=value` text.

OpenCR (per reply): `crc` (corrupt the CRC), `truncate` (cut the reply short),
`delay` (send the reply `delay_time` s late, default 0.1 s: longer than
dynamixel_sdk's timeout), `drop` (no reply), `garbage` (noise bytes before the
reply). LIDAR (per packet): `garbage` (noise bytes before the packet),
`checksum` (a wrong checksum), `drop` (packet lost), `truncate` (packet cut short).
Probabilities are in [0, 1]. Draws come from a generator seeded by the robot's seed.
"""
from typing import Dict, Tuple

import numpy as np

OPENCR_FAULTS = ("crc", "truncate", "delay", "drop", "garbage")
LIDAR_FAULTS = ("garbage", "checksum", "drop", "truncate")
OPTIONS = {"delay_time": 0.1, "garbage_bytes": 8.0}  # non-probability settings and defaults


class FaultError(ValueError):
    pass


def parse_faults(text: str, allowed: Tuple[str, ...]) -> Dict[str, float]:
    """`"crc=0.1,garbage=0.01"` -> {"crc": 0.1, "garbage": 0.01}; unknown keys and bad values rejected."""
    settings = {}
    for item in filter(None, (part.strip() for part in (text or "").split(","))):
        key, separator, value = item.partition("=")
        key = key.strip()
        if not separator:
            raise FaultError(f"fault {item!r} needs a value: {key}=<probability>")
        if key not in allowed and key not in OPTIONS:
            raise FaultError(f"unknown fault {key!r}; known: {', '.join(allowed + tuple(OPTIONS))}")
        try:
            number = float(value)
        except ValueError:
            raise FaultError(f"fault {key}={value!r} is not a number") from None
        if key in allowed and not 0.0 <= number <= 1.0:
            raise FaultError(f"fault {key}={number} must be a probability in [0, 1]")
        if key in OPTIONS and number < 0:
            raise FaultError(f"{key}={number} must not be negative")
        settings[key] = number
    return settings


class FaultInjector:
    """Draws faults for one device; settings can be replaced while it runs."""

    def __init__(self, allowed: Tuple[str, ...], seed: int = 0, settings: Dict[str, float] = None):
        self.allowed = allowed
        self._random = np.random.default_rng(seed)
        self.settings = dict(settings or {})
        self.counts = {name: 0 for name in allowed}

    def configure(self, text: str):
        self.settings = parse_faults(text, self.allowed)

    def happens(self, name: str) -> bool:
        probability = self.settings.get(name, 0.0)
        if probability > 0.0 and self._random.random() < probability:
            self.counts[name] += 1
            return True
        return False

    def option(self, name: str) -> float:
        return self.settings.get(name, OPTIONS[name])

    def garbage(self) -> bytes:
        count = max(1, int(self.option("garbage_bytes")))
        return bytes(self._random.integers(0, 256, count, dtype=np.uint8))

    def cut(self, data: bytes) -> bytes:
        """A prefix of data, at least one byte shorter."""
        return data[:int(self._random.integers(0, max(1, len(data) - 1)))]

    def describe(self) -> str:
        return ",".join(f"{key}={value:g}" for key, value in sorted(self.settings.items())) or "none"
