"""Independent random streams per subsystem, spawned from one episode key.

An episode's randomness is split by name: ``"start"``, ``"deck"``, ``"wind"``, ``"sensor.tof"``,
``"sensor.imu"``, ``"navigation"``, ... Each name gets its own ``numpy.random.Generator`` from
``SeedSequence(entropy=key, spawn_key=(crc32(name),))``, so a subsystem's draws depend on the
episode key and its own name only: adding a sensor, changing the camera model or a noise preset
never shifts the start, the deck motion or the wind of a seed.
"""

from __future__ import annotations

import zlib

import numpy as np

from ihrcf_env.core.checks import check_int

#: Episode keys are drawn in [0, KEY_RANGE).
KEY_RANGE = 2**63


def stream_id(name: str) -> int:
    """The stable integer of a stream name (CRC-32 of its UTF-8 bytes)."""
    return zlib.crc32(name.encode("utf-8"))


class SeedStreams:
    """Named, independent generators of one episode (``key``: a non-negative integer)."""

    def __init__(self, key: int) -> None:
        self.key = check_int("key", key, low=0)

    @classmethod
    def from_generator(cls, rng: np.random.Generator) -> SeedStreams:
        """Streams keyed by one draw from ``rng`` (consecutive episodes of one seeded env differ)."""
        return cls(int(rng.integers(0, KEY_RANGE)))

    def sequence(self, name: str) -> np.random.SeedSequence:
        """The ``SeedSequence`` of the stream ``name``."""
        return np.random.SeedSequence(entropy=self.key, spawn_key=(stream_id(name),))

    def generator(self, name: str) -> np.random.Generator:
        """A new generator of the stream ``name`` (the same draws every call)."""
        return np.random.default_rng(self.sequence(name))


__all__ = [
    "KEY_RANGE",
    "SeedStreams",
    "stream_id",
]
