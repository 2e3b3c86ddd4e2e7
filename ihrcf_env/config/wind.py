"""Wind and disturbance configuration: :class:`WindParams` (mean wind and Dryden gusts with a drag
model) and the :class:`Disturbance` interface of user force models. The wind itself is
:class:`ihrcf_env.sim.disturbances.Wind`. SI units, world frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from ihrcf_env.core.checks import check_fields


@runtime_checkable
class Disturbance(Protocol):
    """World-frame force (N) on the drone's centre of mass as a function of time and state."""

    def reset(self, rng: np.random.Generator) -> None:
        """Start of an episode: draw this episode's random parameters from ``rng``."""

    def __call__(
        self, t: float, position: Sequence[float], velocity: Sequence[float]
    ) -> tuple[float, float, float]:
        """Force (N, world frame) at time ``t`` (s) for the drone at ``position`` (m) with
        ``velocity`` (m/s)."""
        ...


#: Physical bounds (inclusive) of :class:`DragModel`'s fields: a 10 g micro drone to a 100 kg
#: multirotor, air from 10 km altitude to a cold sea-level day.
DRAG_BOUNDS: dict[str, tuple[float, float]] = {
    "mass": (0.01, 100.0),
    "mcoef_xy": (0.0, 10.0),
    "mcoef_z": (0.0, 10.0),
    "bcoef": (1.0, 1e5),
    "rho": (0.1, 2.0),
}


DRAG_UNITS = {"mass": "kg", "mcoef_xy": "1/s", "mcoef_z": "1/s", "bcoef": "kg/m^2", "rho": "kg/m^3"}


@dataclass(frozen=True)
class DragModel:
    """Aerodynamic force on the drone from its velocity through the air ``v_a`` (world, m/s), in
    the form of PX4's multirotor drag model (EKF2 wind estimation, ``src/modules/ekf2/
    params_drag.yaml``)::

        F = -mass (mcoef_xy v_a_xy + mcoef_z v_a_z) - mass 0.5 rho |v_a| v_a / bcoef        (N)

    The linear term is the propellers' momentum (rotor) drag, proportional to the thrust and so,
    near hover, to the mass (Mahony, Kumar & Corke, "Multirotor aerial vehicles", IEEE RAM 19(3),
    2012); the quadratic one the airframe's bluff-body drag with ballistic coefficient ``bcoef =
    mass / CdA``. Defaults are PX4's (``EKF2_MCOEF`` = 0.15 1/s, ``EKF2_BCOEF_X/Y`` = 100 kg/m^2,
    its starting values for a generic 1-2 kg quadrotor such as the X500); the vertical momentum
    drag is taken equal to the horizontal one for lack of a better figure. Rotor drag identified
    on small racing quadrotors is larger (about 0.4-0.5 1/s: Faessler, Franchi & Scaramuzza, IEEE
    RA-L 3(2), 2018). At 5 m/s a 1.2 kg drone feels 0.9 + 0.2 = 1.1 N (a 5 deg lean)."""

    mass: float = 1.2  # kg, the simulated quadrotor's (QuadParams.mass)
    mcoef_xy: float = 0.15  # 1/s
    mcoef_z: float = 0.15  # 1/s
    bcoef: float = 100.0  # kg/m^2
    rho: float = 1.225  # kg/m^3, sea-level air

    def __post_init__(self) -> None:
        check_fields(self, lambda f: f"DragModel.{f}", DRAG_BOUNDS, DRAG_UNITS)

    def force(self, air_velocity: Sequence[float]) -> tuple[float, float, float]:
        """Force (N, world) for the velocity through the air ``air_velocity`` (m/s, world)."""
        vx, vy, vz = (float(v) for v in air_velocity)
        m = self.mass
        q = m * 0.5 * self.rho / self.bcoef * math.sqrt(vx * vx + vy * vy + vz * vz)
        lin_xy, lin_z = m * self.mcoef_xy, m * self.mcoef_z
        return (-(lin_xy + q) * vx, -(lin_xy + q) * vy, -(lin_z + q) * vz)


#: Physical bounds (inclusive) of :class:`WindParams`' real fields: mean winds to a storm (40 m/s),
#: heights within the Dryden low-altitude model's range (1000 ft).
WIND_BOUNDS: dict[str, tuple[float, float]] = {
    "mean_speed_min": (0.0, 40.0),
    "mean_speed_max": (0.0, 40.0),
    "height": (0.1, 300.0),
    "turbulence": (0.0, 5.0),
    "min_advection": (0.01, 40.0),
    "sample_dt": (1e-3, 10.0),
}


WIND_UNITS = {
    "mean_speed_min": "m/s",
    "mean_speed_max": "m/s",
    "height": "m",
    "min_advection": "m/s",
    "sample_dt": "s",
}


@dataclass(frozen=True)
class WindParams:
    """Parameters of :class:`Wind` (SI units).

    Each episode draws a mean wind speed uniform in ``[mean_speed_min, mean_speed_max]`` (m/s,
    horizontal, at most 40; the default 0-5 m/s spans calm to a gentle breeze, Beaufort 0-3) blowing towards a
    direction uniform in [0, 2 pi) (rad from world +x, counter-clockwise). Gusts are Dryden
    turbulence (:func:`dryden_low_altitude`) at ``height`` above the surface (default 5 m, a small
    ship's deck), scaled by ``turbulence`` (0: steady wind), with the mean wind as W20. The frozen
    turbulence field is carried past the hovering drone by the mean wind (Taylor's hypothesis), so
    the correlation time of each component is ``L / V`` with ``V = max(mean speed, min_advection)``.
    Each component is a first-order Gauss-Markov process (the Dryden longitudinal form, used for all
    three axes: same variance and integral scale as Dryden's second-order lateral/vertical filters)
    sampled every ``sample_dt`` s and linearly interpolated, so the wind is a function of time only.
    """

    mean_speed_min: float = 0.0
    mean_speed_max: float = 5.0
    height: float = 5.0
    turbulence: float = 1.0
    min_advection: float = 1.0  # m/s
    sample_dt: float = 0.05  # s
    drag: DragModel = field(default_factory=DragModel)

    def __post_init__(self) -> None:
        check_fields(self, lambda f: f"wind {f}", WIND_BOUNDS, WIND_UNITS)
        if self.mean_speed_min > self.mean_speed_max:
            raise ValueError(
                "wind mean speeds need mean_speed_min <= mean_speed_max (m/s), got "
                f"{self.mean_speed_min!r}, {self.mean_speed_max!r}"
            )
        if not isinstance(self.drag, DragModel):
            raise TypeError(f"wind drag must be a DragModel, got {type(self.drag).__name__} {self.drag!r}")


__all__ = [
    "DRAG_BOUNDS",
    "DRAG_UNITS",
    "WIND_BOUNDS",
    "WIND_UNITS",
    "Disturbance",
    "DragModel",
    "WindParams",
]
