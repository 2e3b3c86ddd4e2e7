"""Physical constants, defined once for the whole package (SI units)."""

#: Standard gravity used by the simulator, the IMU model and the controllers (m/s^2).
GRAVITY: float = 9.81

__all__ = [
    "GRAVITY",
]
