"""Vision/ToF landing controller on a moving deck, from the drone's own sensing only.

For ``action_mode="velocity"`` of ``ihrcf_env/DeckHover-v0``. The controller reads only
``obs["imu"]``, ``obs["ihrcf"]``, ``obs["ranges"]`` and ``obs["ranges_valid"]``, never
``obs["ground_truth"]`` or ``info``, so it runs unchanged on a real drone's sensing. Phases:

1. **approach**: centre over the tag with the IHRCF x/y (level, heading frame), align the heading
   with the IHRCF yaw (modulo 90 deg: the deck is square) and descend to ``hold_height`` (0.65 m:
   the 0.4 m tag and its quiet zone leave the 60 deg view below ~0.4-0.55 m depending on the offset).
2. **hold**: keep centred at ``hold_height`` while two small filters track the deck: an alpha-beta
   filter on the deck height (drone altitude from integrating the IMU's vertical acceleration, kept
   from drifting by the integral of the drone's own vertical commands, minus the ToF plane height
   below the drone) gives the heave velocity, and alpha-beta filters on the
   horizontal components of the deck normal in the level frame (from the IHRCF attitude, or from a
   plane fitted to the four ToF hits when the tag is not seen) give the tilt and its rate.
   The drop is committed when the relative tilt *predicted at touchdown* and the heave velocity
   are small (the deck near the top/bottom of its heave or moving slowly), so the drone does not
   arrive while the deck is tilted beyond the 10 deg limit. On the "paper" profile the deck tilts
   more than 10 deg from ~3.5 s to ~13.5 s, so with the deck started at t = 0 the drone waits at the hold
   height and lands at ~16 s.
3. **drop**: centring continues while the tag is seen, then zero lateral command (the autopilot
   holds position once the tag leaves the image); vertical command = estimated deck heave velocity
   minus the approach speed (0.35 m/s, 0.25 m/s in the last 15 cm), on the ToF ranges, until the
   legs touch.

Without a tag detection (e.g. a frame the detector misses) the drone holds its x/y and creeps down
on the ranges until the tag is found; after ``tag_timeout`` it may commit on the ranges alone as long
as all four beams see a plane (i.e. the drone is over the deck).

For higher starts in wind (``ihrcf_env/DeckLanding-v1``, :mod:`ihrcf_env.control.policies`) some
:class:`LandingConfig` options, all off by default (v0's behaviour), fly the height on the estimate
while the ranges are missing or disagree (``estimate_height``), climb to re-acquire a lost tag
(``reacquire_speed``), forget and clip the heave estimate (``heave_timeout``,
``max_deck_velocity``), and :attr:`Measurement.velocity_z` replaces the integrated accelerometer by
the autopilot's vertical velocity.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.control.filters import AlphaBeta
from ihrcf_env.core.checks import check_bool, check_real, is_real, set_field
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.frames import matrix_from_euler, matrix_from_quat, wrap_angle
from ihrcf_env.core.geometry import fit_plane
from ihrcf_env.core.rig import SensorRig

_HALF_PI = math.pi / 2
#: Bounds (inclusive) of :class:`LandingConfig`'s real fields.
LANDING_BOUNDS: dict[str, tuple[float, float]] = {
    "leg_length": (0.0, 2.0),
    "hold_height": (0.05, 20.0),
    "approach_speed": (0.01, 10.0),
    "drop_speed": (0.01, 10.0),
    "touch_speed": (0.01, 10.0),
    "slow_zone": (0.0, 5.0),
    "k_xy": (0.0, 100.0),
    "max_xy_speed": (0.0, 20.0),
    "k_z": (0.0, 100.0),
    "k_yaw": (0.0, 100.0),
    "centred_tolerance": (0.0, 10.0),
    "height_tolerance": (0.0, 10.0),
    "settle_time": (0.0, 1e4),
    "commit_tilt": (0.0, _HALF_PI),
    "max_tilt_now": (0.0, _HALF_PI),
    "max_deck_speed": (0.0, 10.0),
    "tag_timeout": (0.0, 1e4),
    "drop_lag": (0.0, 100.0),
    "heave_alpha": (0.0, 1.0),
    "heave_beta": (0.0, 2.0),
    "tilt_alpha": (0.0, 1.0),
    "tilt_beta": (0.0, 2.0),
    "drift_k1": (0.0, 100.0),
    "drift_k2": (0.0, 100.0),
    "drift_k3": (0.0, 100.0),
    "tof_agreement": (0.0, 100.0),
    "reacquire_speed": (0.0, 10.0),
    "reacquire_after": (0.0, 1e4),
    "reacquire_height": (0.0, 100.0),
    "heave_timeout": (0.0, 1e4),
    "max_deck_velocity": (0.0, 100.0),
    "commit_below": (0.0, 100.0),
    "lean_tau": (0.0, 100.0),
    "dead_reckon": (0.0, 100.0),
}
#: Fields for which ``inf`` (the default) switches the feature off.
LANDING_OFF_AT_INF = frozenset({"heave_timeout", "max_deck_velocity", "commit_below"})
LANDING_UNITS = {
    **{k: "m" for k in ("leg_length", "hold_height", "slow_zone", "centred_tolerance", "height_tolerance")},
    **{k: "m" for k in ("tof_agreement", "reacquire_height", "commit_below")},
    **{k: "m/s" for k in ("approach_speed", "drop_speed", "touch_speed", "max_xy_speed", "max_deck_speed")},
    **{k: "m/s" for k in ("reacquire_speed", "max_deck_velocity")},
    **{k: "s" for k in ("settle_time", "tag_timeout", "drop_lag", "reacquire_after", "heave_timeout")},
    **{k: "s" for k in ("lean_tau", "dead_reckon")},
    **{k: "rad" for k in ("commit_tilt", "max_tilt_now")},
    "k_xy": "1/s",
    "k_z": "1/s",
    "k_yaw": "1/s",
    "drift_k1": "1/s",
    "drift_k2": "1/s^2",
    "drift_k3": "1/s^3",
}


@dataclass(frozen=True)
class LandingConfig:
    """Tunables of :class:`LandingController` (metres, seconds, radians)."""

    leg_length: float = 0.10  # legs below the body origin
    hold_height: float = 0.65  # body origin above the deck while waiting for a window
    approach_speed: float = 0.4  # max vertical speed in the approach
    drop_speed: float = 0.35  # relative approach speed in the drop, high above the deck
    touch_speed: float = 0.25  # relative approach speed in the last ``slow_zone`` of clearance
    slow_zone: float = 0.15
    k_xy: float = 1.2  # 1/s, lateral centring gain
    max_xy_speed: float = 0.4
    k_z: float = 1.5  # 1/s, height gain
    k_yaw: float = 1.0  # 1/s, heading alignment gain (0 disables)
    centred_tolerance: float = 0.05  # horizontal error to allow the drop
    height_tolerance: float = 0.06
    settle_time: float = 0.8  # s of good hold before the first commit decision (filters warm up)
    commit_tilt: float = math.radians(7.0)  # predicted relative tilt at touchdown
    max_tilt_now: float = math.radians(9.0)  # relative tilt allowed at the commit itself
    max_deck_speed: float = 0.10  # |heave velocity| allowed at the commit
    tag_timeout: float = 4.0  # s without the tag before committing on the ranges alone
    drop_lag: float = 0.4  # s added to the drop-time estimate (the autopilot's velocity lag)
    heave_alpha: float = 0.35
    heave_beta: float = 0.06
    tilt_alpha: float = 0.2
    tilt_beta: float = 0.015
    # Third-order complementary filter of the drone's altitude: the IMU's vertical acceleration at
    # high frequency, the autopilot's commanded altitude at low frequency, and an accelerometer bias
    # state (a real MEMS accelerometer is off by up to ~20 mg = 0.2 m/s^2, which a second-order
    # filter turns into a steady velocity error). Gains put the three poles at -0.2 rad/s.
    drift_k1: float = 0.6  # 1/s, IMU altitude pulled towards the commanded altitude
    drift_k2: float = 0.12  # 1/s^2
    drift_k3: float = 0.008  # 1/s^3, accelerometer bias estimate
    # Fly on the estimate's height when the ToF ranges are missing (beyond their reach, e.g. a high
    # start) or disagree with it by more than ``tof_agreement`` (a cone straddling the deck's edge).
    estimate_height: bool = False
    tof_agreement: float = 0.15  # m
    # Tag lost for ``reacquire_after`` s before the drop: climb at ``reacquire_speed`` (m/s; 0: wait
    # in place) up to ``reacquire_height`` above the hold height, where the view is wider.
    reacquire_speed: float = 0.0
    reacquire_after: float = 0.3
    reacquire_height: float = 0.4
    # The heave filter is forgotten after ``heave_timeout`` s without ToF heights, and its rate is
    # clipped to +-``max_deck_velocity`` (m/s) where it is used (inf: as before).
    heave_timeout: float = math.inf
    max_deck_velocity: float = math.inf
    # A teacher's option (DAgger, ``ihrcf_env.rl.imitation``): once the tag has been seen and the
    # drone is more than ``commit_below`` m under the hold height, the drop is committed (the
    # learner's own early descent is labelled as a drop, not as a climb back to the hold; inf: off).
    commit_below: float = math.inf
    # Leaning into the wind (options for v2, all off by default). ``axis_centring``: centre the tag
    # on the camera's optical axis rather than straight below (the drone holds upwind of the tag by
    # its height times the tangent of its lean, low-passed with time constant ``lean_tau`` s, so the
    # tag stays in the body-fixed camera's view; the offset shrinks to the legs' length times that
    # tangent at touchdown). ``relative_tilt``: the commit gates compare the deck's predicted normal
    # with the drone's (low-passed) up axis, not with the vertical. ``full_plane_tilt``: the ToF
    # plane feeds the deck-normal filters only when all four beams hit one plane. ``dead_reckon``:
    # in the drop, a lost tag's last position is carried for up to that many s, moved by the
    # lateral commands (the autopilot tracks them), and centring goes on towards it (0: off).
    axis_centring: bool = False
    lean_tau: float = 1.0
    relative_tilt: bool = False
    full_plane_tilt: bool = False
    dead_reckon: float = 0.0
    # ``dead_reckon_nav``: the lost tag moves against the drone's measured horizontal velocity
    # (:attr:`Measurement.velocity_xy`, e.g. the autopilot's) rather than its commands, so gusts
    # that push the drone are accounted for.
    dead_reckon_nav: bool = False
    # ``trust_full_plane``: with ``estimate_height``, the ToF height is kept when all four beams lie
    # on one plane even if the estimate disagrees (a diverging estimate must not steer the drop).
    trust_full_plane: bool = False

    def __post_init__(self) -> None:
        flags = ("axis_centring", "relative_tilt", "full_plane_tilt", "dead_reckon_nav", "trust_full_plane")
        for flag in ("estimate_height", *flags):
            check_bool(f"LandingConfig.{flag}", getattr(self, flag))
        for attr, (low, high) in LANDING_BOUNDS.items():
            name = f"LandingConfig.{attr}"
            value = getattr(self, attr)
            if attr in LANDING_OFF_AT_INF and is_real(value) and value == math.inf:
                set_field(self, attr, math.inf)
                continue
            try:
                v = check_real(name, value, LANDING_UNITS.get(attr, ""), low=low, high=high)
            except ValueError as e:
                if attr in LANDING_OFF_AT_INF:
                    raise ValueError(f"{e} (or inf: off)") from None
                raise
            set_field(self, attr, v)


@dataclass
class Measurement:
    """One step's sensing in the level heading frame (x forward along the yaw, y left, z up)."""

    rotation_level: NDArray[np.float64]  # level-from-body (roll and pitch only)
    tag_xy: NDArray[np.float64] | None  # deck origin, horizontal, from IHRCF
    tag_yaw: float | None  # deck yaw in the body frame (IHRCF)
    tag_normal: NDArray[np.float64] | None  # deck normal, level frame (IHRCF)
    tof_height: float | None  # vertical distance body origin -> deck plane below it
    tof_normal: NDArray[np.float64] | None  # normal of the plane through the ToF hits, level frame
    tof_full: bool  # all four beams valid and on one plane
    accel_z: float  # world vertical acceleration (m/s^2, gravity removed)
    tag_height: float | None = None  # height of the body origin above the deck origin (estimate)
    velocity_z: float | None = None  # the drone's world vertical velocity (m/s), e.g. the autopilot's
    velocity_xy: NDArray[np.float64] | None = None  # its horizontal velocity (m/s, level frame)


def _tilt(nx: float, ny: float) -> float:
    """Angle between the vertical and a unit normal with horizontal components ``nx``, ``ny``."""
    return math.asin(min(1.0, math.hypot(nx, ny)))


class LandingController:
    """Vision/ToF landing controller for ``action_mode="velocity"``; see the module docstring.

    Call :meth:`reset` at every episode start, then :meth:`act` once per control step.

    Args:
        control_hz: the env's control rate (``env.unwrapped.config.world.control_hz``).
        max_velocity: the env's action scale (m/s, m/s, m/s, rad/s).
        rig: the ToF/camera geometry (the drone's own, not ground truth).
        config: tunables.
        estimator: the observation key of the deck-pose estimate to steer on ("ihrcf", "fused", ...).
    """

    def __init__(
        self,
        control_hz: int = 20,
        max_velocity: Sequence[float] = (1.0, 1.0, 1.0, 1.0),
        rig: SensorRig | None = None,
        config: LandingConfig | None = None,
        estimator: str = "ihrcf",
    ) -> None:
        if estimator == "ground_truth":
            raise ValueError("estimator: the landing controller flies on its own sensing, not ground truth")
        self.estimator = estimator
        self.dt = 1.0 / float(control_hz)
        self.max_velocity = np.asarray(max_velocity, dtype=np.float64)
        self.rig = rig if rig is not None else SensorRig()
        self.sensors = self.rig.sensor_positions_body
        self.cfg = config if config is not None else LandingConfig()
        self.heave = AlphaBeta(self.cfg.heave_alpha, self.cfg.heave_beta)
        self.nx = AlphaBeta(self.cfg.tilt_alpha, self.cfg.tilt_beta)
        self.ny = AlphaBeta(self.cfg.tilt_alpha, self.cfg.tilt_beta)
        self.reset()

    def reset(self) -> None:
        """Forget everything (call at every episode start)."""
        self.phase = "approach"
        self.t = 0.0
        self.vz_drone = 0.0  # world vertical velocity, IMU-integrated
        self.accel_bias = 0.0  # estimated offset of the IMU's vertical acceleration (m/s^2)
        self.z_drone = 0.0  # altitude relative to the start, IMU-integrated
        self.z_cmd = 0.0  # integral of the commanded vertical velocity (the autopilot tracks it)
        self.prev_accel_z: float | None = None
        self.heave.reset()
        self.nx.reset()
        self.ny.reset()
        self.settled_for = 0.0
        self.since_tag = 0.0
        self.since_range = 0.0  # s without a ToF height of the deck
        self.seen_tag = False
        self.height: float | None = None
        self.commit_time: float | None = None
        self.lean = np.zeros(2)  # low-passed horizontal components of the drone's up axis (level frame)
        self.lean_z = 1.0
        self.lean_ready = False
        self.last_tag: NDArray[np.float64] | None = None  # dead-reckoned tag position (level, m)

    # -- sensing ---------------------------------------------------------------------------
    def measure(self, obs: Mapping[str, Any]) -> Measurement:
        """Turn the observation (the deck-pose estimate, ranges, IMU) into level-frame quantities."""
        R_wb = matrix_from_quat(np.asarray(obs["imu"]["quaternion"], dtype=np.float64))
        yaw = math.atan2(R_wb[1, 0], R_wb[0, 0])
        c, s = math.cos(yaw), math.sin(yaw)
        Rz_T = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
        R_lb = Rz_T @ R_wb
        accel_z = float((R_wb @ np.asarray(obs["imu"]["linear_acceleration"], dtype=np.float64))[2] - GRAVITY)

        tag_level = tag_yaw = tag_normal = None
        est = obs[self.estimator]
        if int(est["valid"]):
            tag_level = R_lb @ np.asarray(est["position"], dtype=np.float64)
            roll, pitch, tag_yaw = (float(v) for v in est["euler"])
            tag_normal = R_lb @ matrix_from_euler(roll, pitch, tag_yaw)[:, 2]
        return self.measure_level(
            R_lb, accel_z, tag_level, tag_yaw, tag_normal, obs["ranges"], obs["ranges_valid"]
        )

    def measure_level(
        self,
        R_lb: NDArray[np.float64],
        accel_z: float,
        tag_level: NDArray[np.float64] | None,
        tag_yaw: float | None,
        tag_normal: NDArray[np.float64] | None,
        ranges: Any,
        ranges_valid: Any,
        velocity_z: float | None = None,
        velocity_xy: Any = None,
    ) -> Measurement:
        """The :class:`Measurement` of quantities already in the level heading frame: ``R_lb``
        (level-from-body), the world vertical acceleration ``accel_z`` (m/s^2, gravity removed),
        the deck origin ``tag_level`` (m), yaw (rad) and normal from the estimate (None: no valid
        estimate), and the ToF ``ranges`` (m) with their validity; ``velocity_z`` (m/s, optional):
        the drone's vertical velocity from its navigation, flown on instead of the integrated
        accelerometer (whose offset, up to ~0.5 m/s^2 on a BMI088, the altitude filter only learns
        over tens of seconds); ``velocity_xy`` (m/s, level frame, optional): its horizontal
        velocity, which dead-reckons a lost tag when ``dead_reckon_nav``."""
        tag_xy = tag_height = None
        if tag_level is not None:
            tag_xy = tag_level[:2]
            tag_height = -float(tag_level[2])
        ranges = np.asarray(ranges, dtype=np.float64)
        valid = np.asarray(ranges_valid).astype(bool)
        tof_height = tof_normal = None
        tof_full = False
        if valid.sum() >= 3:
            # beams run along the optical axis (body -z) from the sensors
            hits = self.sensors[valid] + ranges[valid, None] * np.array([0.0, 0.0, -1.0])
            q = hits @ R_lb.T
            # plane n.x = d in the level frame (unit n, n_z >= 0): least squares on 4, exact on 3
            tof_normal, d = fit_plane(q)
            tof_height = -d / float(tof_normal[2])  # depth of the plane below the body origin
            resid = q @ tof_normal - d
            tof_full = bool(valid.all() and np.max(np.abs(resid)) < 0.05)
        elif valid.any():
            tof_height = float(np.mean(ranges[valid])) - float(self.sensors[0, 2])
        return Measurement(
            R_lb,
            tag_xy,
            tag_yaw,
            tag_normal,
            tof_height,
            tof_normal,
            tof_full,
            accel_z,
            tag_height,
            velocity_z,
            None if velocity_xy is None else np.asarray(velocity_xy, dtype=np.float64)[:2],
        )

    def _update_state(self, m: Measurement) -> None:
        """Integrate the IMU altitude, update the heave and deck-normal filters and the tag timers."""
        c, dt = self.cfg, self.dt
        if m.velocity_z is not None:  # the autopilot's vertical velocity: integrate it
            self.z_drone += 0.5 * (self.vz_drone + m.velocity_z) * dt
            self.vz_drone = m.velocity_z
        else:
            a_prev = m.accel_z if self.prev_accel_z is None else self.prev_accel_z
            v_new = self.vz_drone + (0.5 * (a_prev + m.accel_z) - self.accel_bias) * dt
            self.z_drone += 0.5 * (self.vz_drone + v_new) * dt
            self.vz_drone = v_new
            # complementary correction towards the commanded altitude: removes the integration drift
            # and, through the bias state, a constant accelerometer offset
            e = self.z_cmd - self.z_drone
            self.z_drone += c.drift_k1 * e * dt
            self.vz_drone += c.drift_k2 * e * dt
            self.accel_bias -= c.drift_k3 * e * dt
        self.prev_accel_z = m.accel_z
        tof_height = m.tof_height
        if c.estimate_height and tof_height is not None and m.tag_height is not None:
            full = c.trust_full_plane and m.tof_full  # four beams on one plane: on the deck
            if abs(tof_height - m.tag_height) > c.tof_agreement and not full:
                tof_height = None  # beams straddling the deck's edge (or off it): trust the estimate
        self.height = tof_height
        if self.height is None and c.estimate_height:
            self.height = m.tag_height
        deck_z = None if tof_height is None else self.z_drone - tof_height
        self.since_range = 0.0 if deck_z is not None else self.since_range + dt
        if self.since_range > c.heave_timeout:
            self.heave.reset()  # no ranges for a while: forget the heave (do not coast on its rate)
        self.heave.update(deck_z, dt)
        up = m.rotation_level[:, 2]
        if not self.lean_ready or c.lean_tau <= 0.0:
            self.lean, self.lean_z, self.lean_ready = up[:2].copy(), float(up[2]), True
        else:
            k = min(1.0, dt / c.lean_tau)
            self.lean += k * (up[:2] - self.lean)
            self.lean_z += k * (float(up[2]) - self.lean_z)
        tof_n = m.tof_normal if (m.tof_full or not c.full_plane_tilt) else None
        n = m.tag_normal if m.tag_normal is not None else tof_n
        self.nx.update(None if n is None else float(n[0]), dt)
        self.ny.update(None if n is None else float(n[1]), dt)
        if m.tag_xy is not None:
            self.seen_tag = True
            self.since_tag = 0.0
            self.last_tag = np.array(m.tag_xy, dtype=np.float64)
        else:
            self.since_tag += dt
            if self.last_tag is not None and c.dead_reckon_nav and m.velocity_xy is not None:
                self.last_tag -= m.velocity_xy * dt  # the drone's motion over the last step

    # -- decisions -------------------------------------------------------------------------
    @property
    def deck_velocity(self) -> float:
        """Estimated vertical velocity of the deck below the drone (m/s, up positive)."""
        if self.heave.x is None:
            return 0.0
        limit = self.cfg.max_deck_velocity
        return float(min(max(self.heave.v, -limit), limit))

    def predicted_tilt(self, horizon: float) -> float | None:
        """Deck tilt from the vertical (rad; the relative tilt once the drone is level at touchdown),
        extrapolated ``horizon`` seconds ahead from the filtered deck normal."""
        if self.nx.x is None or self.ny.x is None:
            return None
        nx, ny = self.nx.x + self.nx.v * horizon, self.ny.x + self.ny.v * horizon
        if not self.cfg.relative_tilt:
            return _tilt(nx, ny)
        nz = math.sqrt(max(0.0, 1.0 - nx * nx - ny * ny))
        u = np.array([self.lean[0], self.lean[1], self.lean_z])
        cos = (nx * u[0] + ny * u[1] + nz * u[2]) / max(float(np.linalg.norm(u)), 1e-9)
        return math.acos(max(-1.0, min(1.0, cos)))

    def drop_duration(self) -> float:
        """Expected time (s) from the commit to touchdown."""
        c = self.cfg
        clearance = max((self.height or c.hold_height) - c.leg_length, 0.0)
        fast = max(clearance - c.slow_zone, 0.0)
        return fast / c.drop_speed + min(clearance, c.slow_zone) / c.touch_speed + c.drop_lag

    def _ready_to_commit(self, m: Measurement) -> bool:
        """True when the predicted tilt at touchdown and the heave velocity allow the drop."""
        c = self.cfg
        if self.settled_for < c.settle_time:
            return False
        horizon = self.drop_duration()
        now, later = self.predicted_tilt(0.0), self.predicted_tilt(horizon)
        if now is None or later is None:
            return False
        mid = self.predicted_tilt(0.5 * horizon)
        # the tilt that matters is the one at touchdown; the mid-point guards against a bad extrapolation
        tilt_ok = max(later, mid if mid is not None else later) < c.commit_tilt and now < c.max_tilt_now
        heave_ok = abs(self.deck_velocity) < c.max_deck_speed
        return tilt_ok and heave_ok

    def axis_point(self) -> NDArray[np.float64]:
        """Where the camera's (low-passed) optical axis meets the deck plane, horizontally, relative
        to the drone (m, level frame); zero unless ``axis_centring``."""
        h = self.height
        if not self.cfg.axis_centring or h is None or self.lean_z <= 0.1:
            return np.zeros(2)
        depth = max(h + float(self.rig.camera_position[2]), 0.0)  # the camera sits below the centre
        return -self.lean * depth / self.lean_z

    def _centring(self, tag_xy: NDArray[np.float64]) -> tuple[float, float]:
        """Horizontal velocity (m/s, level frame) that brings the tag under the camera's axis
        (straight below without ``axis_centring``), clipped."""
        c = self.cfg
        err = np.asarray(tag_xy, dtype=np.float64) - self.axis_point()
        vx, vy = (float(np.clip(c.k_xy * v, -c.max_xy_speed, c.max_xy_speed)) for v in err)
        return vx, vy

    def act(self, obs: Mapping[str, Any]) -> NDArray[np.float32]:
        """Velocity action in [-1, 1]^4 for this observation."""
        return self.act_measured(self.measure(obs))

    def act_measured(self, m: Measurement) -> NDArray[np.float32]:
        """Velocity action in [-1, 1]^4 for this step's :class:`Measurement`."""
        c = self.cfg
        self._update_state(m)
        self.t += self.dt
        vx = vy = yaw_rate = 0.0
        h = self.height

        if self.phase in ("approach", "hold"):
            if m.tag_xy is not None:
                vx, vy = self._centring(m.tag_xy)
                if m.tag_yaw is not None and c.k_yaw > 0:
                    yaw_rate = c.k_yaw * float(wrap_angle(m.tag_yaw, math.pi / 2))
            if h is None:
                vz = 0.0  # nothing below: hold
            elif not self.seen_tag:
                # creep down on the ranges until a detection (a new scale often brings the tag back)
                vz = -0.15 if h > c.hold_height else 0.0
            else:  # height on the ranges, riding the heave
                vz = float(np.clip(-c.k_z * (h - c.hold_height), -c.approach_speed, c.approach_speed))
                vz += self.deck_velocity
                lost = m.tag_xy is None and self.since_tag > c.reacquire_after
                if c.reacquire_speed > 0 and lost and h < c.hold_height + c.reacquire_height:
                    vz = c.reacquire_speed  # climb until the tag is back in view
            off_axis = None if m.tag_xy is None else float(np.hypot(*(m.tag_xy - self.axis_point())))
            centred = off_axis is not None and off_axis < c.centred_tolerance
            near = h is not None and abs(h - c.hold_height) < c.height_tolerance
            if self.phase == "approach" and near:
                self.phase = "hold"
            if self.seen_tag and h is not None and h < c.hold_height - c.commit_below:
                self.phase = "drop"  # the teacher's option (LandingConfig.commit_below)
                self.commit_time = self.t
            if self.phase == "hold":
                # without the tag for a while, all four beams on one plane say "over the deck" enough
                blind = self.since_tag > c.tag_timeout and m.tof_full
                self.settled_for = self.settled_for + self.dt if ((centred or blind) and near) else 0.0
                if self._ready_to_commit(m):
                    self.phase = "drop"
                    self.commit_time = self.t

        if self.phase == "drop":
            clearance = (h - c.leg_length) if h is not None else c.slow_zone
            speed = c.drop_speed if clearance > c.slow_zone else c.touch_speed
            vz = self.deck_velocity - speed
            if m.tag_xy is not None:  # keep centring while the tag is still in view
                vx, vy = self._centring(m.tag_xy)
            elif self.last_tag is not None and self.since_tag <= c.dead_reckon:
                vx, vy = self._centring(self.last_tag)

        if c.axis_centring and self.lean_z > 0.1 and (m.tag_xy is not None or self.phase == "drop"):
            # the axis point moves as the height changes: feed its motion forward
            rate = vz - self.deck_velocity  # commanded rate of the height above the deck (m/s)
            vx += float(self.lean[0]) / self.lean_z * rate
            vy += float(self.lean[1]) / self.lean_z * rate
        cmd = np.clip(np.array([vx, vy, vz, yaw_rate]) / self.max_velocity, -1.0, 1.0)
        if self.last_tag is not None and not (c.dead_reckon_nav and m.velocity_xy is not None):
            self.last_tag -= cmd[:2] * self.max_velocity[:2] * self.dt  # against the commanded motion
        self.z_cmd += float(cmd[2] * self.max_velocity[2]) * self.dt  # the autopilot's altitude set-point
        return cmd.astype(np.float32)


__all__ = [
    "LANDING_BOUNDS",
    "LANDING_OFF_AT_INF",
    "LANDING_UNITS",
    "LandingConfig",
    "LandingController",
    "Measurement",
]
