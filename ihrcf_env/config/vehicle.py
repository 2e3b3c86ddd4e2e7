"""The vehicle's configuration: quadrotor parameters, the velocity autopilot's gains and the
autopilot's navigation feedback (truth or a drifting GNSS/INS estimate). Frozen dataclasses checked
in ``__post_init__``; the simulated vehicle lives in :mod:`ihrcf_env.sim.drone` and
:mod:`ihrcf_env.sim.navigation`. SI units, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_bool, check_fields, check_reals, set_field
from ihrcf_env.core.constants import GRAVITY

#: Physical bounds (inclusive) of :class:`QuadParams`' fields (``inertia``: each axis): a 50 g micro
#: quadrotor to a 50 kg multirotor.
QUAD_BOUNDS: dict[str, tuple[float, float]] = {
    "mass": (0.05, 50.0),
    "inertia": (1e-6, 10.0),
    "arm": (0.02, 2.0),
    "kf": (1e-9, 1e-2),
    "km": (1e-11, 1e-3),
    "max_rotor_speed": (10.0, 1e4),
    "motor_tau": (0.0, 1.0),
    "drag": (0.0, 10.0),
    "rotor_radius": (0.005, 1.5),
}


QUAD_UNITS = {
    "mass": "kg",
    "inertia": "kg m^2",
    "arm": "m",
    "kf": "N/(rad/s)^2",
    "km": "N m/(rad/s)^2",
    "max_rotor_speed": "rad/s",
    "motor_tau": "s",
    "drag": "N s/m",
    "rotor_radius": "m",
}


@dataclass(frozen=True)
class QuadParams:
    """Physical constants of the quadrotor (SI units). Mass/inertia must match the URDF."""

    mass: float = 1.2
    inertia: tuple[float, float, float] = (0.0123, 0.0123, 0.0224)
    arm: float = 0.15
    kf: float = 5.886e-6  # N / (rad/s)^2
    km: float = 9.4e-8  # N m / (rad/s)^2  (km / kf = 0.016 m)
    max_rotor_speed: float = 1000.0  # rad/s -> 4 kf w_max^2 = 23.5 N, thrust-to-weight 2.0
    motor_tau: float = 0.015  # s, rotor speed time constant
    drag: float = 0.08  # N s/m, linear aerodynamic drag
    #: m, propeller radius (ground effect, :mod:`ihrcf_env.sim.ground_effect`): an 8-inch propeller,
    #: the largest that clears its neighbour on 0.15 m arms (adjacent hubs 0.212 m apart) and the
    #: size whose static thrust matches ``kf`` (see docs/flight-model.md)
    rotor_radius: float = 0.1016

    def __post_init__(self) -> None:
        lo, hi = QUAD_BOUNDS["inertia"]
        set_field(
            self, "inertia", check_reals("QuadParams.inertia", self.inertia, 3, "kg m^2", low=lo, high=hi)
        )
        check_fields(
            self,
            lambda f: f"QuadParams.{f}",
            {k: v for k, v in QUAD_BOUNDS.items() if k != "inertia"},
            QUAD_UNITS,
        )

    @property
    def max_thrust(self) -> float:
        """Per motor (N)."""
        return self.kf * self.max_rotor_speed**2

    @property
    def thrust_to_weight(self) -> float:
        return 4 * self.max_thrust / (self.mass * GRAVITY)

    @property
    def motor_xy(self) -> NDArray[np.float64]:
        d = self.arm / math.sqrt(2)
        return np.array([[d, d], [d, -d], [-d, -d], [-d, d]])

    @property
    def spin(self) -> NDArray[np.float64]:
        """+1 for rotors turning counter-clockwise seen from above."""
        return np.array([1.0, -1.0, 1.0, -1.0])

    @property
    def mixer(self) -> NDArray[np.float64]:
        """(4, 4) map from motor thrusts (N) to (collective thrust N, torque x, y, z N m)."""
        xy = self.motor_xy
        ratio = self.km / self.kf
        return np.vstack([np.ones(4), xy[:, 1], -xy[:, 0], -self.spin * ratio])


#: Bounds (inclusive) of :class:`VelocityGains`' fields (``k_att``, ``k_rate``: each axis).
GAIN_BOUNDS: dict[str, tuple[float, float]] = {
    "kp_pos": (0.0, 100.0),
    "kd_vel": (0.0, 100.0),
    "ki_pos": (0.0, 100.0),
    "kp_z": (0.0, 100.0),
    "kd_z": (0.0, 100.0),
    "ki_z": (0.0, 100.0),
    "max_tilt": (math.radians(1.0), math.radians(80.0)),
    "k_att": (0.0, 100.0),
    "k_rate": (0.0, 10.0),
    "leash": (0.01, 100.0),
    "i_limit": (0.0, 100.0),
    "i_limit_z": (0.0, 100.0),
    "dob_tau": (0.0, 100.0),
}


GAIN_UNITS = {
    "kp_pos": "1/s^2",
    "kd_vel": "1/s",
    "ki_pos": "1/s^3",
    "kp_z": "1/s^2",
    "kd_z": "1/s",
    "ki_z": "1/s^3",
    "max_tilt": "rad",
    "k_att": "N m/rad",
    "k_rate": "N m s/rad",
    "leash": "m",
    "i_limit": "m/s^2",
    "i_limit_z": "m/s^2",
    "dob_tau": "s",
}


@dataclass(frozen=True)
class VelocityGains:
    """Cascaded controller gains: position/velocity (outer) and attitude/rate (inner).

    The horizontal loop is a PID on the position error plus a disturbance observer's feed-forward
    (see :class:`VelocityController`). ``i_limit`` is the largest horizontal acceleration (m/s^2)
    the integral term may command, and the largest disturbance the observer may cancel: the default
    covers the drag of a 15 m/s wind on the default quadrotor (about 3.6 m/s^2, see
    ``docs/flight-model.md``) with a margin, and stays below the ``max_tilt`` authority
    (``g tan(30 deg)`` = 5.7 m/s^2). ``i_limit_z`` bounds the vertical integral term the same way.
    ``dob_tau`` is the observer's time constant (s); 0 turns the observer off."""

    kp_pos: float = 3.0  # 1/s^2
    kd_vel: float = 3.5  # 1/s
    ki_pos: float = 0.6  # 1/s^3
    kp_z: float = 4.0
    kd_z: float = 4.0
    ki_z: float = 1.0
    max_tilt: float = math.radians(30.0)
    k_att: tuple[float, float, float] = (4.5, 4.5, 1.6)  # N m / rad
    k_rate: tuple[float, float, float] = (0.38, 0.38, 0.3)  # N m s / rad
    leash: float = 0.5  # m, max position error before the set-point is dragged along
    i_limit: float = 5.0  # m/s^2, horizontal integral term and disturbance estimate clamp
    i_limit_z: float = 2.0  # m/s^2, vertical integral term clamp
    dob_tau: float = 0.4  # s, disturbance observer time constant (0: off)
    #: the wind-holding loop (anti-windup + disturbance observer); False: the classic loop, a
    #: per-axis integrator clamp of :data:`CLASSIC_I_CLAMP` (m s) and no observer
    wind_hold: bool = False

    def __post_init__(self) -> None:
        for name in ("k_att", "k_rate"):
            lo, hi = GAIN_BOUNDS[name]
            set_field(
                self, name, check_reals(f"VelocityGains.{name}", getattr(self, name), 3, low=lo, high=hi)
            )
        set_field(self, "wind_hold", check_bool("VelocityGains.wind_hold", self.wind_hold))
        scalars = {k: v for k, v in GAIN_BOUNDS.items() if k not in ("k_att", "k_rate")}
        check_fields(self, lambda f: f"VelocityGains.{f}", scalars, GAIN_UNITS)


#: Autopilot feedback modes.
FEEDBACK_MODES: tuple[str, ...] = ("truth", "estimated")


#: Physical bounds (inclusive) of :class:`NavigationErrors`' fields: from an RTK fix to a poor
#: standalone GNSS, position errors correlated over a second to hours, velocity errors over a
#: millisecond to hours.
NAVIGATION_ERROR_BOUNDS: dict[str, tuple[float, float]] = {
    "horizontal_sigma": (0.0, 100.0),
    "vertical_sigma": (0.0, 100.0),
    "position_time_constant": (1.0, 1e4),
    "velocity_time_constant": (1e-3, 1e4),
    "velocity_noise": (0.0, 10.0),
}


NAVIGATION_ERROR_UNITS = {
    "horizontal_sigma": "m",
    "vertical_sigma": "m",
    "position_time_constant": "s",
    "velocity_time_constant": "s",
    "velocity_noise": "m/s",
}


@dataclass(frozen=True)
class NavigationErrors:
    """Error figures of the GNSS/INS estimate (metres, seconds, m/s; 1 sigma, per axis).

    ==========================  =========  =========================================================
    field                       default    source
    ==========================  =========  =========================================================
    horizontal_sigma            0.71 m     Xsens MTi-G-700 GNSS/INS (user manual MT0605P sec. 4.4):
                                           horizontal position 1.0 m STD (SBAS), split over x and y
    vertical_sigma              0.33 m     barometric height: Bosch BMP388 relative accuracy
                                           +-0.08 hPa = +-0.66 m, taken as 2 sigma
    position_time_constant      300 s      assumption: GNSS/baro errors stay correlated for minutes
    velocity_time_constant      2 s        assumption: the EKF's velocity error decorrelates over a
                                           few GNSS fixes
    velocity_noise              0.02 m/s   assumption; the white part, with the correlated part
                                           (0.029 m/s horizontally) well inside the MTi-G-700's
                                           0.1 m/s 1 sigma velocity figure (quoted at 30 m/s)
    ==========================  =========  =========================================================
    """

    horizontal_sigma: float = 0.71
    vertical_sigma: float = 0.33
    position_time_constant: float = 300.0
    velocity_time_constant: float = 2.0
    velocity_noise: float = 0.02

    def __post_init__(self) -> None:
        check_fields(self, lambda f: f"NavigationErrors.{f}", NAVIGATION_ERROR_BOUNDS, NAVIGATION_ERROR_UNITS)

    @property
    def position_sigma(self) -> NDArray[np.float64]:
        """(3,) stationary std of the position error per world axis (m)."""
        return np.array([self.horizontal_sigma, self.horizontal_sigma, self.vertical_sigma])

    @property
    def velocity_sigma(self) -> NDArray[np.float64]:
        """(3,) stationary std ``sigma_v`` of the correlated velocity error per axis (m/s)."""
        tp, tv = self.position_time_constant, self.velocity_time_constant
        return self.position_sigma * math.sqrt((tp + tv) / (tv * tp * tp))

    def drift_std(self, horizon: float) -> NDArray[np.float64]:
        """(3,) std of the change of the position error over ``horizon`` seconds (m) for the
        continuous model: ``sqrt(2 (C(0) - C(T)))`` with the position error's autocovariance (a
        first-order filter of pole ``a = 1/tau_p`` driven by exponentially correlated noise of
        variance ``sigma_v^2`` and rate ``b = 1/tau_v``)
        ``C(T) = sigma_v^2 (a e^{-bT} - b e^{-aT}) / (a (a^2 - b^2))``. This is the drift of a drone
        holding its estimated position (what the autopilot flies on)."""
        a = 1.0 / self.position_time_constant
        b = 1.0 / self.velocity_time_constant
        if a == b:
            b *= 1.0 + 1e-9
        sv2 = self.velocity_sigma**2
        T = horizon
        c0 = sv2 * (a - b) / (a * (a * a - b * b))
        cT = sv2 * (a * math.exp(-b * T) - b * math.exp(-a * T)) / (a * (a * a - b * b))
        return np.sqrt(np.maximum(2.0 * (c0 - cT), 0.0))


@dataclass(frozen=True)
class NavigationConfig:
    """``feedback``: ``"truth"``, ``"estimated"`` (default :class:`NavigationErrors`) or a
    :class:`NavigationErrors` (an estimate with custom figures)."""

    feedback: str | NavigationErrors = "truth"

    def __post_init__(self) -> None:
        if not isinstance(self.feedback, NavigationErrors) and self.feedback not in FEEDBACK_MODES:
            raise ValueError(
                f"autopilot_feedback must be one of {FEEDBACK_MODES} or a NavigationErrors, "
                f"got {self.feedback!r}"
            )

    @property
    def errors(self) -> NavigationErrors | None:
        """The error figures, or None when the autopilot flies on the truth."""
        if isinstance(self.feedback, NavigationErrors):
            return self.feedback
        return None if self.feedback == "truth" else NavigationErrors()


__all__ = [
    "FEEDBACK_MODES",
    "GAIN_BOUNDS",
    "GAIN_UNITS",
    "NAVIGATION_ERROR_BOUNDS",
    "NAVIGATION_ERROR_UNITS",
    "QUAD_BOUNDS",
    "QUAD_UNITS",
    "NavigationConfig",
    "NavigationErrors",
    "QuadParams",
    "VelocityGains",
]
