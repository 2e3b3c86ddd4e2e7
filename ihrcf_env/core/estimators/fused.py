"""The fused deck-pose estimator: IHRCF + ATDA's attitude + the IMU + a causal Kalman filter.

The paper's conclusion (section 5) proposes IMUs "to address ... noise among the ToF range sensors".
With VL53L1X-like ranges (sigma 10 mm) the plane through four touch points 14 cm apart tilts by
sigma_r / (a sqrt 2) ~ 4 deg per frame, so single-frame IHRCF angles (~3 deg MAE) fall behind ATDA's
(~0.4 deg), and the tilt error also moves IHRCF's position: a corner at lateral distance x on a plane
tilted by d_theta moves x^2 d_theta / z sideways along its camera ray, so the tag centre moves
(s/2)^2 / z ~ 4 cm per radian (measured correlation 0.98 between IHRCF's x error and its pitch
error). :class:`FusedEstimator` removes both, using only what a real drone logs (a
:class:`~ihrcf_env.core.estimators.base.SensorFrame` per camera frame: time, tag corners, the four
ranges and their validity, an IMU sample); pure numpy / scipy plus the package's pure estimators.

Design (every number below is a field of :class:`FusedParams`):

1. **A gravity-aligned filter frame.** The deck (a ship) moves slowly and smoothly, the drone fast.
   Measurements are mapped with the IMU attitude ``R_wb`` of their frame to the relative position
   ``r = R_wb p_body`` (deck origin minus drone, world axes) and the deck attitude
   ``R_wd = R_wb R_bd``; the filter smooths these slow quantities and maps back with the *current*
   IMU attitude at output: ``p_body = R_wb^T r``, ``R_bd = R_wb^T R_wd``. The drone's own rotations
   never pass through the smoother, so the output follows them without lag. A slowly varying IMU
   attitude error (tilt error, yaw drift) cancels in the round trip (the filter's world is the
   IMU's world); only its frame-to-frame jitter reaches the output.
2. **Relative translation**: per world axis a kinematic Kalman filter on ``[r, v, b]`` with
   ``r'' = b - a_drone``: the drone's acceleration ``a_drone = R_wb f_body + g_world`` from the
   accelerometer is the control input (``accel_noise`` white noise on it), and ``b`` (random walk,
   ``accel_drift``) absorbs the deck's own acceleration, the accelerometer bias and the gravity
   leak of an IMU tilt error. Without an IMU sample the input is zero (``b`` then carries the
   drone's acceleration too). The accelerometer sample of a frame is held over the interval that
   ends at it (``accel_hold="end"``) or averaged with the previous one (``"trapezoid"``). The
   gyro is not integrated: the sample's attitude is already the autopilot filter's integral of
   it (body rates are only checked to be finite).
3. **Deck attitude**: the same filter on the Z-Y-X Euler angles of ``R_wd`` (state
   ``[angles, rates, angular accelerations]``, white angular acceleration ``angle_accel_noise``
   plus random-walk angular acceleration ``angle_drift``): the deck tilts < ~20 deg, far from
   gimbal lock; the yaw innovation is wrapped and the state angles kept in (-pi, pi].
   **Interacting multiple models**: both filters run under three deck-motion levels at once
   (``accel_drift`` and ``angle_drift``: a quiet, a moderate and an agile deck), mixed through a
   Markov switch (mean sojourn ``model_switch_time``) and weighted by their likelihoods. The
   paper's slow profile (periods 20-130 s) then gets the long averaging it allows and a sea state
   (periods 4-14 s) the agility it needs: with one model tuned for the paper's deck, the sea
   state's roll error was 1.7 deg; tuned for the sea state, the paper's was 0.4 deg; the IMM gives
   0.23 and 0.27 deg. **IMU attitude wander**: the tilt error of a real attitude filter wanders
   (``imu_attitude_walk``); seen from the filter frame it moves the deck's attitude, the relative
   position (``e x r``) and, through the gravity leak, ``b``; all three get that random walk.
4. **Measurements**, each with its own covariance and a Mahalanobis gate (``gate_probability`` of
   the chi-square of its dimension); a rejected block is skipped and counted:

   * *IHRCF tilt* (roll, pitch): variance from the least-squares plane through the valid touch
     points, ``sigma_r^2 (A^T A)^-1`` (A rows ``[1, x_i, y_i]``), largest slope eigenvalue, plus
     ``ihrcf_tilt_floor``; ``sigma_r`` is the range noise **estimated online** from the plane-fit
     residual of the four ranges (one degree of freedom per frame: the "twist" of four coplanar
     touch points is pure noise), averaged in the log domain with the chi-square(1) bias
     correction (robust to the occasional huge residual, and it falls to ~0 within a few frames
     with exact ranges), starting from ``tof_sigma``. So the same filter trusts IHRCF's tilt with
     ideal ranges and ATDA's with noisy ones, without being told which.
   * *ATDA attitude* (optional, ``use_atda_attitude``; needs K): roll, pitch and yaw with
     ``atda_tilt_sigma`` (scaled by (depth / ``reference_depth``)^2) and ``atda_yaw_sigma``
     (scaled by depth). Its flip-ambiguity prior is the filter's own predicted rotation.
   * *IHRCF refit* (``refit=True``): IHRCF's 3-D corners lie on the camera rays of their pixels
     (rays defined by the range-to-pixel table, not by K). Once the attitude is updated, the rays
     are intersected with the plane of the filter's deck normal placed at the mean of the valid
     touch points' offsets along it, and the tag model is fitted again (Kabsch). This removes the
     tilt-induced lateral error above; the refit's depth has variance ``sigma_r^2 / m`` (m valid
     ranges) plus the filter's tilt variance times the squared distance from the touch points'
     centroid, along the tag centre's camera ray, plus ``ihrcf_lateral_floor`` /
     ``ihrcf_depth_floor``. The refit's position and yaw (``ihrcf_yaw_floor`` at the reference
     depth, plus ``ihrcf_yaw_per_range * sigma_r / depth``) are the IHRCF measurements. Without the
     refit (or before the filter has an attitude) the plain IHRCF position is used with the
     plane's variance at the tag centre and the tilt lever ``(s/2)^2 / depth`` laterally.
   * *ATDA position* (``use_atda_position``, on by default): ``atda_depth_sigma`` (scaled by
     depth^2) along the tag's camera ray and a wide ``atda_lateral_sigma`` (scaled by depth), so it
     serves the depth only. Why: a ToF sensor's constant offset (the simulator's VL53L1X draws
     one per sensor and episode, sigma 2.5 mm) biases every range-based depth for the whole flight
     and no filtering removes it; ATDA's depth has its own bias (~1.4 mm at 1 m in the simulator,
     corners detected slightly inside the tag; on a real camera also the focal-length error of the
     calibration, which IHRCF is free of), but the two are independent, and the blend halves the
     worst episodes (full realistic preset, seed 0: fused Z MAE 3.67 -> 2.36 mm) for ~0.1 mm on
     the typical ones. Turn it off to keep the fused depth independent of the camera calibration.

   * *Common-mode range offset* (optional, ``range_offset_sigma`` > 0; needs K and the ATDA
     position): an offset shared by the four ranges shifts IHRCF's depth and is invisible in the
     ranges themselves, but ATDA's depth is an independent reference. A separate two-state filter
     of random constants, the range offset (prior ``range_offset_sigma``) and ATDA's own depth
     bias (prior ``atda_depth_bias_sigma``), is updated each frame with the difference of the
     refit's depth (or the plain IHRCF depth) and ATDA's, variance ``sigma_r^2 / m`` plus ATDA's
     depth variance (1-dof gate); the estimated offset is subtracted from the ranges of the next
     frames before IHRCF. The observation wrapper turns it on with the VL53L1X model (prior
     ``offset_sigma / 2``, the mean of four independent offsets).

   The sequence per frame: predict to the frame's time (IMU input); ATDA attitude and IHRCF tilt;
   refit with the updated normal; IHRCF yaw; IHRCF position (range-offset update); ATDA position.
5. **Validity.** The first frame with a valid IHRCF estimate (or ATDA's, when its position is
   used) initialises the state from its first measurement of each filter, not gated (IHRCF's
   attitude first: it has no flip ambiguity); the derivatives start at zero with
   ``init_velocity_sigma``, ``init_accel_sigma``, ``init_rate_sigma``, ``init_angle_accel_sigma``.
   The output is ``valid = False`` ("converging: k/10 updates") until ``min_updates`` frames were
   accepted and the position and angle 1-sigma are below ``valid_position_sigma`` /
   ``valid_angle_sigma``; once converged it stays valid while it predicts on the IMU between
   measurements (tag lost, frames rejected). A filter (position or attitude) without an accepted
   measurement for more than ``lost_timeout`` forgets its state ("tag lost for 1.05 s > 1 s",
   then "not initialised: tag not found") and re-initialises from the next measurement; so does
   one whose every measurement was gated out for ``max_rejections`` frames in a row (it lost
   track, e.g. after a deck jump). Frames with a non-finite IMU sample or a time going backwards
   are ignored (state unchanged; invalid with the reason); an unknown time (NaN) counts as
   ``nominal_dt`` after the last. The output is never NaN.

``PoseEstimate.residual`` of the fused estimate is the position 1-sigma (m, square root of the
covariance trace); :attr:`FusedEstimator.diagnostics` tells what each frame accepted or rejected and
the current range-noise estimate. ATDA needs the camera matrix: without K only IHRCF is fused.

Measured in the simulator (``experiments.accuracy``: the paper's hover 1 m over the "paper" deck
profile, 20 Hz, 600 frames, seed 0; mean absolute error X/Y/Z mm, roll/pitch/yaw deg):

=====================  ======  ======================  =========================
ToF                    source  X / Y / Z (mm)          roll / pitch / yaw (deg)
=====================  ======  ======================  =========================
ideal                  IHRCF   0.36 / 0.34 / 0.06      0.006 / 0.006 / 0.061
ideal                  ATDA    1.03 / 0.49 / 1.54      0.373 / 0.353 / 0.064
ideal                  fused   0.36 / 0.34 / 0.06      0.006 / 0.006 / 0.056
realistic (VL53L1X)    IHRCF   1.24 / 0.94 / 1.74      1.228 / 1.541 / 0.119
realistic (VL53L1X)    ATDA    1.03 / 0.49 / 1.54      0.373 / 0.353 / 0.064
realistic (VL53L1X)    fused   0.44 / 0.38 / 1.15      0.271 / 0.250 / 0.058
white, sigma 10 mm     IHRCF   2.45 / 2.29 / 4.58      3.132 / 3.276 / 0.272
white, sigma 10 mm     ATDA    1.03 / 0.49 / 1.54      0.373 / 0.353 / 0.064
white, sigma 10 mm     fused   0.44 / 0.40 / 1.22      0.275 / 0.245 / 0.055
=====================  ======  ======================  =========================

Fused is invalid for its first 8 frames ("converging"); IHRCF loses 39 frames of the white-noise
run to its residual check. With the realistic IMU (BMI088 noise and biases, 0.5 deg attitude-filter
tilt error) as well: fused 0.48 / 0.40 / 1.24 mm, 0.287 / 0.286 / 0.059 deg. The full realistic
preset (``sensor_preset="realistic"``, drone tracking the deck on ``fused``), seeds 0 / 1 / 2: fused
Z 2.36 / 0.71 / 1.03 mm, X and Y <= 0.38 mm, angles <= 0.19 deg; seed 0 draws ToF offsets of
+3.0 to +5.1 mm on all four sensors, a depth bias (IHRCF Z 3.54 mm) that no filter removes and the
ATDA depth halves. With the range-offset state (the wrapper's default for the VL53L1X model:
``range_offset_sigma`` 1.25 mm, ``atda_depth_bias_sigma`` 0.75 mm), 600 frames, seeds 0-4: fused Z
2.96 / 0.76 / 1.39 / 1.23 / 0.99 mm without it, 1.88 / 0.93 / 1.53 / 1.23 / 1.36 mm with it (X, Y
and the angles unchanged): the simulated ATDA depth is itself biased (~+1.5 mm), so the episodes
with small offsets lose up to 0.4 mm for the worst one's gain. ~1.2 ms per frame in the env on one
core, its own IHRCF and ATDA included (0.67 ms of filter work when they are shared with the other
estimators).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators.atda import atda_choose, atda_frame_candidates
from ihrcf_env.core.estimators.base import ImuSample, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.ihrcf import IHRCFCorners, TouchPixels, ihrcf_fit, ihrcf_measure
from ihrcf_env.core.frames import (
    R_BODY_CAM,
    as_array,
    euler_from_matrix,
    matrix_from_euler,
    matrix_from_quat,
)
from ihrcf_env.core.linalg import mahalanobis2, spd_inverse
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

_DEG = math.pi / 180.0
#: E[ln X] for X ~ chi-square(1): the bias of the log-domain average of one-dof variance samples.
_LOG_CHI2_1_MEAN = -1.2703628454614782
_G_WORLD = np.array([0.0, 0.0, -GRAVITY])
_R_CAM_BODY = np.ascontiguousarray(R_BODY_CAM.T)
_DIAG3 = np.diag_indices(3)


@dataclass(frozen=True)
class FusedParams:
    """Parameters of :class:`FusedEstimator` (SI units: m, s, rad). Defaults: the simulator's
    realistic sensors (VL53L1X ranges, sigma a few mm to 10 mm; a BMI088 IMU behind an attitude
    filter with 0.5 deg tilt error; a 512x512 camera with f = 443 px; a 0.4 m tag; 20 Hz) over a
    deck between the paper's slow profile and a sea state. The range noise is estimated online,
    so they also suit exact ranges; with an exact IMU attitude, ``imu_attitude_walk = 0`` smooths
    a little more.

    Range sensors and IHRCF:
        tof_sigma: prior range noise, 1 sigma (m), until the online estimate takes over.
        tof_sigma_window: frames of the online range-noise average (exponential, log domain).
        tof_sigma_min: floor of a one-frame range-noise sample (m).
        ihrcf_tilt_floor: IHRCF tilt noise with exact ranges (rad).
        ihrcf_yaw_floor: IHRCF yaw noise with exact ranges at ``reference_depth`` (rad; x depth).
        ihrcf_yaw_per_range: IHRCF yaw noise per unit of ``sigma_r / depth`` (rad).
        ihrcf_lateral_floor: IHRCF lateral position noise with exact ranges at ``reference_depth``
            (m; x depth).
        ihrcf_depth_floor: IHRCF depth noise with exact ranges (m).
        refit: intersect IHRCF's corner rays with the filter's deck plane (see the module).
    ATDA (needs K):
        use_atda_attitude, use_atda_position: fuse ATDA's attitude / position.
        atda_tilt_sigma: roll/pitch noise at ``reference_depth`` (rad; x (depth/ref)^2).
        atda_yaw_sigma: yaw noise at ``reference_depth`` (rad; x depth/ref).
        atda_lateral_sigma: lateral position noise at ``reference_depth`` (m; x depth/ref): wider
            than ATDA's (~1 mm, biased) so the refit's lateral position prevails.
        atda_depth_sigma: depth noise at ``reference_depth`` (m; x (depth/ref)^2).
        reference_depth: depth of the values above (m).
    Common-mode range offset (needs K and ``use_atda_position``):
        range_offset_sigma: prior 1-sigma (m) of a constant offset common to the four ranges,
            estimated against ATDA's depth and subtracted from the ranges (0: no such state).
        atda_depth_bias_sigma: prior 1-sigma (m) of ATDA's own constant depth bias, the other
            half of that comparison.
    Motion models (white-noise spectral densities):
        accel_noise: accelerometer input noise, (m/s^2)/sqrt(Hz).
        accel_drift: random walk of the unmodelled relative acceleration ``b`` (deck acceleration,
            accelerometer bias, gravity leak), (m/s^3)/sqrt(Hz): one level per model of the IMM
            (default: a quiet, a moderate and an agile deck).
        angle_accel_noise: white angular acceleration of the deck, (rad/s^2)/sqrt(Hz).
        angle_drift: random walk of the deck's angular acceleration, (rad/s^3)/sqrt(Hz), one level
            per model.
        model_switch_time: mean time (s) the IMM's Markov chain stays in one model.
        imu_attitude_walk: wander of the IMU attitude's tilt error, (rad/s)/sqrt(Hz): a random walk
            of the filtered roll and pitch, of the relative position (``e x r``) and, through the
            gravity leak, of the horizontal ``b`` (default: a Gauss-Markov tilt error of 0.5 deg
            over 5 s, ``sigma sqrt(2 / tau)``, the simulator's realistic IMU).
        accel_hold: ``"end"`` (a frame's accelerometer sample holds over the interval ending at it)
            or ``"trapezoid"`` (mean of the previous and current samples).
    Initial uncertainty (1 sigma) of the derivatives:
        init_velocity_sigma (m/s), init_accel_sigma (m/s^2), init_rate_sigma (rad/s),
        init_angle_accel_sigma (rad/s^2).
    Gating, validity, timing:
        gate_probability: chi-square probability of the Mahalanobis gate of each measurement.
        max_rejections: consecutive frames in which every measurement of one filter (position or
            attitude) was rejected, after which that filter starts again from the measurements.
        min_updates: accepted frames before the output is valid.
        valid_position_sigma (m), valid_angle_sigma (rad): largest position and angle 1-sigma at
            which a new state counts as converged (checked until it first does).
        lost_timeout: seconds without an accepted measurement after which a filter (position or
            attitude) drops its state and the output turns invalid.
        nominal_dt: frame interval assumed when a frame's time is unknown (NaN), s.
    """

    tof_sigma: float = 0.010
    tof_sigma_window: int = 100
    tof_sigma_min: float = 1e-5
    ihrcf_tilt_floor: float = 0.01 * _DEG
    ihrcf_yaw_floor: float = 0.08 * _DEG
    ihrcf_yaw_per_range: float = 0.6
    ihrcf_lateral_floor: float = 0.0005
    ihrcf_depth_floor: float = 0.0002
    refit: bool = True
    use_atda_attitude: bool = True
    use_atda_position: bool = True
    atda_tilt_sigma: float = 0.5 * _DEG
    atda_yaw_sigma: float = 0.1 * _DEG
    atda_lateral_sigma: float = 0.003
    atda_depth_sigma: float = 0.002
    reference_depth: float = 1.0
    range_offset_sigma: float = 0.0
    atda_depth_bias_sigma: float = 0.00075
    accel_noise: float = 0.003
    accel_drift: tuple[float, ...] = (0.001, 0.01, 0.1)
    angle_accel_noise: float = 0.002
    angle_drift: tuple[float, ...] = (0.005, 0.05, 0.5)
    model_switch_time: float = 30.0
    imu_attitude_walk: float = 0.0055
    accel_hold: Literal["end", "trapezoid"] = "end"
    init_velocity_sigma: float = 0.5
    init_accel_sigma: float = 0.5
    init_rate_sigma: float = 20 * _DEG
    init_angle_accel_sigma: float = 10 * _DEG
    gate_probability: float = 0.999
    max_rejections: int = 10
    min_updates: int = 10
    valid_position_sigma: float = 0.01
    valid_angle_sigma: float = 3.0 * _DEG
    lost_timeout: float = 1.0
    nominal_dt: float = 0.05

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "accel_hold":
                if v not in ("end", "trapezoid"):
                    raise ValueError(f"accel_hold must be 'end' or 'trapezoid', got {v!r}")
            elif f.name in ("accel_drift", "angle_drift"):
                if not (
                    isinstance(v, tuple)
                    and v
                    and all(
                        isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x) and x >= 0
                        for x in v
                    )
                ):
                    raise ValueError(f"{f.name} must be a non-empty tuple of finite numbers >= 0, got {v!r}")
            elif isinstance(f.default, bool):
                if not isinstance(v, bool):
                    raise TypeError(f"{f.name} must be a bool, got {v!r}")
            elif isinstance(f.default, int):
                if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                    raise ValueError(f"{f.name} must be an int >= 1, got {v!r}")
            else:
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
                    raise ValueError(f"{f.name} must be a finite number >= 0, got {v!r}")
        for name in (
            "tof_sigma",
            "tof_sigma_min",
            "reference_depth",
            "nominal_dt",
            "lost_timeout",
            "model_switch_time",
        ):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability!r}")


# -- the kinematic Kalman filter and its interacting multiple models ------------------------------


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles wrapped to (-pi, pi] (:func:`~ihrcf_env.core.frames.wrap_angle` without the checks)."""
    return math.pi - np.mod(math.pi - a, 2 * math.pi)


@functools.lru_cache(maxsize=8)
def _kinematics(dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per-axis transition ``F1`` (3, 3) of ``[value, rate, acceleration]`` over ``dt`` s, and the
    process-noise shapes of a white rate derivative ``Qw`` and a white acceleration derivative ``Qd``
    (unit spectral density)."""
    F1 = np.array([[1.0, dt, 0.5 * dt * dt], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
    Qw = np.array([[dt**3 / 3, dt**2 / 2, 0.0], [dt**2 / 2, dt, 0.0], [0.0, 0.0, 0.0]])
    Qd = np.array(
        [[dt**5 / 20, dt**4 / 8, dt**3 / 6], [dt**4 / 8, dt**3 / 3, dt**2 / 2], [dt**3 / 6, dt**2 / 2, dt]]
    )
    for m in (F1, Qw, Qd):
        m.setflags(write=False)
    return F1, Qw, Qd


def _per_axis(block: NDArray[np.float64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """The (9, 9) matrix of a per-axis (3, 3) ``block`` scaled by ``weights`` (3,) per axis, in the
    state order ``[values (3), rates (3), accelerations (3)]`` (``kron(block, diag(weights))``)."""
    return (block[:, None, :, None] * np.diag(weights)[None, :, None, :]).reshape(9, 9)


def _largest_eigenvalue(C: NDArray[np.float64]) -> float:
    """Largest eigenvalue of a symmetric (3, 3) matrix (closed form: the trigonometric solution of
    the characteristic cubic, Smith 1961)."""
    (a, b, c), (_, d, e), (_, _, f) = C.tolist()
    q = (a + d + f) / 3.0
    p1 = b * b + c * c + e * e
    a, d, f = a - q, d - q, f - q
    p2 = (a * a + d * d + f * f + 2.0 * p1) / 6.0
    if p2 <= 0.0:  # a multiple of the identity
        return q
    p = math.sqrt(p2)
    det = a * (d * f - e * e) - b * (b * f - e * c) + c * (b * e - d * c)
    r = max(-1.0, min(1.0, det / (2.0 * p * p2)))
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)


class _Imm:
    """Kalman filters of three axes of ``[value, rate, rate of rate]`` (state (9,) ordered
    ``[values (3), rates (3), accelerations (3)]``), as interacting multiple models (Blom and
    Bar-Shalom): the same filter under several process-noise levels (``drifts``, one (3,) density of
    the acceleration's derivative per model), mixed at every prediction through a Markov switch of
    mean sojourn ``switch_time`` s and weighted by their measurement likelihoods. A slow deck selects
    the quiet model (long averaging), a sea-state deck the agile one, without retuning. One model is
    a plain Kalman filter. Gating uses the combined estimate; the counters serve the validity and
    re-initialisation rules. All models are propagated and corrected at once (stacked arrays), and
    every step is written for tiny matrices: a measurement's rows are a contiguous block, so its
    ``H`` is a slice, and the combined estimate is moment-matched only where it is read (the
    measured block for the gate; the state and the values' covariance for the output)."""

    def __init__(
        self,
        sigmas: tuple[float, float, float],
        drifts: list[NDArray[np.float64]],
        q_white: NDArray[np.float64],
        switch_time: float,
        time: float,
        angles: bool = False,
        q_value: NDArray[np.float64] | None = None,
    ) -> None:
        """Initial 1-sigmas ``sigmas`` of (value, rate, acceleration), the same on every axis; the
        models' ``drifts``; white-noise spectral densities ``q_white`` (3,) on the rates' derivative
        (1 sigma per sqrt(Hz)) and ``q_value`` (3, 3) on the values' derivative (value^2/s; constant
        here, a varying one is given to :meth:`predict`); initial ``time`` s."""
        n = len(drifts)
        self.X = np.zeros((n, 9))  # model states
        self.Ps = np.repeat(np.diag(np.repeat(np.square(sigmas), 3))[None], n, axis=0)  # (n, 9, 9)
        self.drifts = np.asarray(drifts, dtype=np.float64)  # (n, 3)
        self.mu = np.full(n, 1.0 / n)
        self.q_white = np.array(q_white, dtype=np.float64)
        self.q_value = np.zeros((3, 3)) if q_value is None else np.array(q_value, dtype=np.float64)
        self.switch_time = switch_time
        self.angles = angles  # values are angles: wrapped innovations and states
        self.frames = 0  # frames with at least one accepted measurement
        self.rejected_run = 0  # consecutive frames whose every measurement was rejected
        self.last_accepted = time  # time of the last accepted measurement, s
        self._x: NDArray[np.float64] | None = None  # combined state, cached until the next change
        self._value_cov: NDArray[np.float64] | None = None  # combined values' covariance, cached
        #: per dt: Markov switch T (n, n), transition F^T (9, 9), process noise (n, 9, 9) (the
        #: filter runs at a fixed frame rate: computed once)
        self._model_cache: dict[float, tuple[NDArray[np.float64], ...]] = {}

    def _model(self, dt: float) -> tuple[NDArray[np.float64], ...]:
        """(T, F^T, Q) of one prediction over ``dt`` s (see :meth:`predict`), cached."""
        hit = self._model_cache.get(dt)
        if hit is not None:
            return hit
        n = len(self.mu)
        T = np.ones((1, 1))  # one model: no switching
        if n > 1:
            stay = math.exp(-dt / self.switch_time)
            T = np.full((n, n), (1.0 - stay) / (n - 1))
            np.fill_diagonal(T, stay)
        F1, Qw, Qd = _kinematics(float(dt))
        Ft = np.ascontiguousarray(_per_axis(F1, np.ones(3)).T)
        Q = _per_axis(Qw, np.square(self.q_white))[None] + np.stack(
            [_per_axis(Qd, np.square(d)) for d in self.drifts]
        )
        Q[:, 0:3, 0:3] += self.q_value * dt
        for m in (T, Ft, Q):
            m.setflags(write=False)
        if len(self._model_cache) >= 8:
            self._model_cache.clear()
        self._model_cache[dt] = (T, Ft, Q)
        return T, Ft, Q

    def _deviations(self, lo: int, hi: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The most probable model's state rows ``lo:hi`` (reference) and every model's deviation
        from it (n, hi - lo), angles wrapped: the mixture is taken around one model, so angles near
        +-pi mix correctly."""
        Xr = self.X[:, lo:hi]
        ref = Xr[int(self.mu.argmax())]
        D = Xr - ref
        if self.angles and lo < 3:
            D[:, : 3 - lo] = _wrap(D[:, : 3 - lo])
        return ref, D

    def _changed(self) -> None:
        self._x = None
        self._value_cov = None

    @property
    def x(self) -> NDArray[np.float64]:
        """The combined (moment-matched) state (9,), values wrapped for angles."""
        if self._x is None:
            ref, D = self._deviations(0, 9)
            x = ref + self.mu @ D
            if self.angles:
                x[0:3] = _wrap(x[0:3])
            self._x = x
        return self._x

    def _mixture_cov(self, covs: NDArray[np.float64], dev: NDArray[np.float64]) -> NDArray[np.float64]:
        """Moment-matched covariance of the models' ``covs`` (n, k, k) about points whose deviations
        from the combined mean are ``dev`` (n, k): ``sum_i mu_i (C_i + d_i d_i^T)``."""
        return np.einsum("n,nij->ij", self.mu, covs) + (dev.T * self.mu) @ dev

    @property
    def value_cov(self) -> NDArray[np.float64]:
        """The combined covariance (3, 3) of the values."""
        if self._value_cov is None:
            D = self._deviations(0, 3)[1]
            self._value_cov = self._mixture_cov(self.Ps[:, 0:3, 0:3], D - self.mu @ D)
        return self._value_cov

    def predict(
        self, dt: float, u: NDArray[np.float64] | None = None, q_value: NDArray[np.float64] | None = None
    ) -> None:
        """Mix the models, then propagate each ``dt`` s: ``u`` (3,) a known acceleration of the
        values, ``q_value`` (3, 3) a white-noise spectral density on the values' derivative
        (value^2/s) added to the constant one for this step; the process noise is the filter's
        (see the constructor) plus each model's drift on the accelerations' derivative."""
        if dt <= 0:
            return
        n = len(self.mu)
        T, Ft, Q0 = self._model(float(dt))
        X, Ps = self.X, self.Ps
        if n > 1:  # mixing: model j starts from the mixture of the models weighted by P(i | j)
            c = self.mu @ T  # predicted model probabilities
            W = T.T * self.mu
            W /= c[:, None]  # W[j, i] = P(i | j) = T[i, j] mu_i / c_j
            ref, D = self._deviations(0, 9)
            mean = W @ D  # (n, 9)
            X = ref + mean
            # sum_i W[j, i] (P_i + (D_i - m_j)(D_i - m_j)^T) = sum_i W[j, i] (P_i + D_i D_i^T) - m_j m_j^T
            G = Ps + D[:, :, None] * D[:, None, :]
            Ps = (W @ G.reshape(n, 81)).reshape(n, 9, 9) - mean[:, :, None] * mean[:, None, :]
            self.mu = c / c.sum()
        X = X @ Ft
        if u is not None:
            X[:, 0:3] += 0.5 * dt * dt * u
            X[:, 3:6] += dt * u
        if self.angles:
            X[:, 0:3] = _wrap(X[:, 0:3])
        Ps = Ft.T @ Ps @ Ft + Q0
        if q_value is not None:
            Ps[:, 0:3, 0:3] += q_value * dt
        self.X = X
        self.Ps = 0.5 * (Ps + Ps.transpose(0, 2, 1))
        self._changed()

    def update(
        self, z: NDArray[np.float64], rows: tuple[int, int], R: NDArray[np.float64], gate: float | None
    ) -> tuple[bool, float]:
        """Measure the values ``rows = (lo, hi)`` (state rows ``lo:hi``, within 0..3) as ``z`` with
        covariance ``R``; gated on the combined estimate (squared Mahalanobis distance beyond
        ``gate``: rejected, nothing changes). Returns (accepted, squared distance)."""
        lo, hi = rows
        mu, Ps = self.mu, self.Ps
        NU = z - self.X[:, lo:hi]  # (n, k) innovation of each model
        if self.angles:
            NU = _wrap(NU)
        Ss = Ps[:, lo:hi, lo:hi] + R  # (n, k, k) innovation covariance of each model (symmetric:
        # the covariances are symmetrised after every change and R is symmetric, see _Measurement)
        # the combined estimate's innovation and covariance (moment matching; sum(mu) = 1)
        nu = mu @ NU
        S = self._mixture_cov(Ss, NU - nu)  # (sum(mu) = 1: the mixture of P + R is P's mixture + R)
        d2 = mahalanobis2(S, nu)
        if not math.isfinite(d2) or (gate is not None and d2 > gate):
            return False, d2
        inverses = spd_inverse(Ss)
        if inverses is None:
            return False, math.inf
        Sinv, logdet = inverses
        # every model: Kalman update (H selects rows lo:hi; gain K = P H^T S^-1; x + K nu and
        # P - K S K^T = P - K (P H^T)^T, symmetrised) and the likelihood of its innovation
        PHt = Ps[:, :, lo:hi]  # (n, 9, k) = P H^T
        y = Sinv @ NU[:, :, None]  # (n, k, 1) = S^-1 nu
        X = self.X + (PHt @ y)[:, :, 0]
        Ps = Ps - (PHt @ Sinv) @ PHt.transpose(0, 2, 1)
        self.Ps = 0.5 * (Ps + Ps.transpose(0, 2, 1))
        if self.angles:
            X[:, 0:3] = _wrap(X[:, 0:3])
        self.X = X
        if len(mu) > 1:
            # Bayes on the model probabilities (mu >= 1e-12 > 0), likelihoods scaled by the largest
            # (plain floats: n numbers)
            loglik = (np.einsum("nk,nk->n", NU, y[:, :, 0]) + logdet).tolist()  # -2 log L
            best = min(loglik)
            w = [m * math.exp(0.5 * (best - ll)) for m, ll in zip(mu.tolist(), loglik, strict=True)]
            total = sum(w)
            w = [max(x / total, 1e-12) for x in w]
            total = sum(w)
            self.mu = np.array([x / total for x in w])
        self._changed()
        return True, d2

    def finite(self) -> bool:
        return bool(np.isfinite(self.X).all() and np.isfinite(self.Ps).all() and np.isfinite(self.mu).all())

    def value_sigma(self) -> float:
        """Largest 1-sigma of the (combined) values."""
        return math.sqrt(max(_largest_eigenvalue(self.value_cov), 0.0))


# -- measurements -------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Measurement:
    """One measurement block in the filter frame: ``z`` over state rows ``rows``, covariance ``R``
    (exactly symmetric)."""

    name: str
    z: NDArray[np.float64]
    rows: tuple[int, int]  # state rows lo:hi
    R: NDArray[np.float64]


@functools.lru_cache(maxsize=32)
def _plane_shape(xy_key: bytes) -> tuple[NDArray[np.float64], float]:
    """``(A^T A)^-1`` (3, 3) of the least-squares plane ``z = c0 + c1 x + c2 y`` through points at
    ``xy`` (m, camera frame; ``xy_key`` its float64 bytes, A rows ``[1, x_i, y_i]``) and the
    largest eigenvalue of its slope block: the plane's covariance and tilt variance per unit
    range variance (the rig is fixed: cached per set of used sensors)."""
    xy = np.frombuffer(xy_key, dtype=np.float64).reshape(-1, 2)
    A = np.column_stack([np.ones(len(xy)), xy])
    C = np.asarray(np.linalg.inv(A.T @ A), dtype=np.float64)
    C.setflags(write=False)
    a, b, c = float(C[1, 1]), 0.5 * float(C[1, 2] + C[2, 1]), float(C[2, 2])
    return C, 0.5 * (a + c) + math.hypot(0.5 * (a - c), b)


def _plane_covariance(xy: NDArray[np.float64], sigma_r: float) -> tuple[NDArray[np.float64], float]:
    """Covariance (3, 3) of ``(c0, c1, c2)`` of the least-squares plane ``z = c0 + c1 x + c2 y``
    through points at ``xy`` (m, camera frame) whose z has noise ``sigma_r`` (m), and its largest
    slope variance (the tilt variance, rad^2)."""
    C, tilt = _plane_shape(np.ascontiguousarray(xy, dtype=np.float64).tobytes())
    var = sigma_r * sigma_r
    return var * C, var * tilt


def _ray_covariance(
    point: NDArray[np.float64],
    R_wc: NDArray[np.float64],
    depth_var: float,
    lateral_var: float,
    depth_floor_var: float,
) -> NDArray[np.float64]:
    """Covariance, in the filter's world axes, of a camera-frame point whose depth error moves it
    along its ray (``depth_var``), plus lateral and depth floors: ``R_wc (dv u u^T + diag(lat, lat,
    floor)) R_wc^T`` with ``u`` the ray through ``point`` scaled to unit depth, written as
    ``dv w w^T + lat I + (floor - lat) c c^T`` (``w = R_wc u``, ``c`` the optical axis): exactly
    symmetric, as the filter needs."""
    w = R_wc @ (point / point[2])
    c = R_wc[:, 2]
    C = depth_var * np.outer(w, w) + (depth_floor_var - lateral_var) * np.outer(c, c)
    C[_DIAG3] += lateral_var
    return C


class FusedEstimator:
    """IHRCF (+ ATDA's attitude) + IMU + causal Kalman filter, as a
    :class:`~ihrcf_env.core.estimators.base.DeckPoseSource` (design in the module docstring).

    Args:
        touch_pixels: the range -> touch-pixel table (IHRCF).
        rig: sensor geometry. tag_size: tag side, m.
        K: (3, 3) camera matrix for ATDA, or None (IHRCF only). dist: distortion coefficients or None.
        max_residual: IHRCF rigid-fit RMS above which its estimate is not used, m.
        params: :class:`FusedParams` (default tuned for the simulator's realistic sensors).
        name: observation key.
    """

    def __init__(
        self,
        touch_pixels: TouchPixels,
        rig: SensorRig,
        tag_size: float,
        K: ArrayLike | None = None,
        dist: ArrayLike | None = None,
        max_residual: float = 0.01,
        params: FusedParams | None = None,
        name: str = "fused",
    ) -> None:
        tag_corners_deck(tag_size)  # validates tag_size
        if not (math.isfinite(max_residual) and max_residual > 0):
            raise ValueError(f"max_residual must be positive (m), got {max_residual!r}")
        if params is not None and not isinstance(params, FusedParams):
            raise TypeError(f"params must be a FusedParams, got {type(params).__name__}")
        self._name = str(name)
        self.touch_pixels = touch_pixels
        self.rig = rig
        self.tag_size = float(tag_size)
        self.K = None if K is None else as_array(K, (3, 3), "K").copy()
        self.dist = None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy()
        self.max_residual = float(max_residual)
        self._camera_position = np.array(rig.camera_position, dtype=np.float64)
        self.params = params if params is not None else FusedParams()
        p = self.params
        self._gate = {k: float(chi2.ppf(p.gate_probability, k)) for k in (1, 2, 3)}
        walk2 = p.imu_attitude_walk**2
        self._q_value_att = np.diag([walk2, walk2, 0.0])  # the IMU tilt wander on the filtered roll, pitch
        self._q_white_pos = np.full(3, p.accel_noise)
        self._q_white_att = np.full(3, p.angle_accel_noise)
        A = np.column_stack([np.ones(4), rig.sensor_xy_cam])
        #: unit vector orthogonal to the columns of A: the residual direction of a plane fit to four ranges
        self._residual_direction = np.linalg.svd(A)[0][:, 3].copy()
        self.reset()

    # -- protocol -------------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """Observation key."""
        return self._name

    def reset(self) -> None:
        """Forget everything: filter state, clock, range-noise estimate, ATDA prior."""
        self._pos: _Imm | None = None
        self._att: _Imm | None = None
        self._time: float | None = None  # time of the last processed frame, s
        self._R_wb: NDArray[np.float64] | None = None
        self._a_world: NDArray[np.float64] | None = None
        self._log_var = 2.0 * math.log(self.params.tof_sigma)  # log of the range variance, m^2
        self._var_weight = 1.0  # pseudo-samples behind _log_var
        self._atda_prior: NDArray[np.float64] | None = None
        #: common-mode range offset and ATDA depth bias (m): estimate (2,) and covariance (2, 2)
        self._bias = np.zeros(2)
        self._bias_P = np.diag([self.params.range_offset_sigma**2, self.params.atda_depth_bias_sigma**2])
        self._converged = False  # both filters met the convergence rule since they were created
        #: What the last :meth:`update` did: accepted / rejected measurement blocks with their
        #: squared Mahalanobis distance, re-initialisations, range noise (m), 1-sigmas (m, rad).
        self.diagnostics: dict[str, Any] = {}

    @property
    def range_sigma(self) -> float:
        """Current estimate of the ToF range noise, 1 sigma (m)."""
        return math.exp(0.5 * self._log_var)

    @property
    def range_offset(self) -> float:
        """Current estimate of the common-mode range offset (m; 0 without that state)."""
        return float(self._bias[0])

    @property
    def initialised(self) -> bool:
        """True while the filter has a state (position and attitude)."""
        return self._pos is not None and self._att is not None

    def motion(self, horizon: float = 0.01) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """The filter's deck motion after the last :meth:`update`, in the filter's (the IMU's) world
        axes: (velocity of the deck origin relative to the drone (3,) m/s, rate of change of the deck
        normal (3,) 1/s, by central differences over +-``horizon`` s of the Euler rates); None until
        the filter has converged (as the pose output's validity) or after it lost its state."""
        if not self._converged or self._pos is None or self._att is None:
            return None
        x_att = self._att.x
        angles, rates = x_att[0:3], x_att[3:6]
        ahead = matrix_from_euler(*(angles + horizon * rates))[:, 2]
        behind = matrix_from_euler(*(angles - horizon * rates))[:, 2]
        return np.array(self._pos.x[3:6]), (ahead - behind) / (2.0 * horizon)

    def update(self, frame: SensorFrame) -> PoseEstimate:
        """Fuse ``frame`` (time non-decreasing) and return the filtered deck pose in the body frame."""
        p = self.params
        self.diagnostics = {"accepted": [], "rejected": [], "reinitialised": []}
        # time (NaN: one nominal interval after the last frame)
        if math.isnan(frame.time):
            t = (self._time + p.nominal_dt) if self._time is not None else 0.0
        else:
            t = frame.time
        if self._time is not None and t < self._time:
            return PoseEstimate.invalid(
                f"time went backwards ({t:.6g} s < {self._time:.6g} s): frame ignored"
            )
        imu = self._imu(frame.imu)
        if isinstance(imu, str):
            return PoseEstimate.invalid(imu)
        R_wb, a_world = imu
        dt = 0.0 if self._time is None else t - self._time
        self._time = t

        # timeouts (each filter forgets its state after lost_timeout without a measurement), then
        # prediction on the IMU
        lost_reason = ""
        for key in ("_att", "_pos"):
            kf = getattr(self, key)
            if kf is not None and t - kf.last_accepted > p.lost_timeout:
                what = "tag lost" if frame.corners is None else f"no {key[1:]} measurement"
                lost_reason = f"{what} for {t - kf.last_accepted:.3g} s > {p.lost_timeout:.3g} s"
                setattr(self, key, None)
                self._converged = False
        if self._att is None and self._pos is None:
            self._atda_prior = None
        u = a_world
        if a_world is not None and p.accel_hold == "trapezoid" and self._a_world is not None:
            u = 0.5 * (a_world + self._a_world)
        self._a_world = a_world
        walk2 = p.imu_attitude_walk**2
        if self._pos is not None:
            r = self._pos.x[0:3]
            q_value = walk2 * (float(r @ r) * np.eye(3) - np.outer(r, r))  # e x r, e the tilt wander
            self._pos.predict(dt, None if u is None else -u, q_value)
        if self._att is not None:
            self._att.predict(dt)

        reason = self._measure(frame, R_wb, t)
        for kf in (self._pos, self._att):
            if kf is not None and not kf.finite():
                self._drop()
                return PoseEstimate.invalid("numerical failure: filter reset")
        return self._output(R_wb, lost_reason or reason)

    # -- internals ----------------------------------------------------------------------------
    def _imu(self, imu: ImuSample | None) -> tuple[NDArray[np.float64], NDArray[np.float64] | None] | str:
        """(R_wb, drone acceleration in the world or None) of a sample, or why the frame is ignored."""
        if imu is None:  # no IMU: the last attitude (identity before any), no acceleration input
            return (self._R_wb if self._R_wb is not None else np.eye(3)), None
        q, f = imu.quaternion, imu.specific_force
        if not math.isfinite(
            float(q @ q) + float(f @ f) + float(imu.angular_velocity @ imu.angular_velocity)
        ):
            return "non-finite IMU sample: frame ignored"  # (or absurdly large: > 1e154)
        if float(q @ q) < 1e-12:
            return "zero IMU quaternion: frame ignored"
        R_wb = matrix_from_quat(q)
        self._R_wb = R_wb
        return R_wb, R_wb @ f + _G_WORLD

    def _drop(self) -> None:
        self._pos = None
        self._att = None
        self._converged = False
        self._atda_prior = None

    def _depth_scale(self, depth: float) -> float:
        return max(depth, 1e-3) / self.params.reference_depth

    def _update_range_noise(self, frame: SensorFrame) -> None:
        """One sample of the range variance from the plane-fit residual of four valid ranges."""
        r = frame.ranges
        if not bool(frame.ranges_valid.all()) or not (np.isfinite(r).all() and r.min() > 0):
            return
        # four points, three plane parameters: the residual is the ranges' component along the
        # one direction orthogonal to the columns [1, x_i, y_i] (one degree of freedom)
        ssr = float(self._residual_direction @ r) ** 2
        sample = math.log(max(ssr, self.params.tof_sigma_min**2)) - _LOG_CHI2_1_MEAN
        self._var_weight = min(self._var_weight + 1.0, float(self.params.tof_sigma_window))
        self._log_var += (sample - self._log_var) / self._var_weight

    def _update_range_offset(self, ihrcf: PoseEstimate, corners: IHRCFCorners, atda: PoseEstimate) -> None:
        """One comparison of IHRCF's depth (the refit's, or the plain one's; offset-corrected
        ranges) with ATDA's: their difference measures the range offset minus ATDA's depth bias,
        both random constants. Uncertainty: the mean of the used ranges and ATDA's depth noise."""
        p = self.params
        X, Y = self._cam_point(ihrcf), self._cam_point(atda)
        d = self._depth_scale(Y[2])
        m = int(np.count_nonzero(corners.ranges_used))
        var = self.range_sigma**2 / max(m, 1) + (p.atda_depth_sigma * d * d) ** 2 + p.ihrcf_depth_floor**2
        bias_P = self._bias_P
        H = np.array([1.0, -1.0])
        nu = (X[2] - Y[2]) - float(H @ self._bias) + self._bias[0]  # raw range depth minus ATDA's
        S = float(H @ bias_P @ H) + var
        if nu * nu / S > self._gate[1]:
            return
        Kg = bias_P @ H / S
        self._bias = self._bias + Kg * nu
        bias_P = bias_P - np.outer(Kg, H @ bias_P)
        self._bias_P = 0.5 * (bias_P + bias_P.T)
        self.diagnostics["range_offset"] = float(self._bias[0])

    def _filtered_R_bd(self, R_wb: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The filter's current deck rotation in the body frame (``R_wb^T R_wd``), or None."""
        if self._att is None:
            return None
        return R_wb.T @ matrix_from_euler(*self._att.x[0:3])

    def _measure(self, frame: SensorFrame, R_wb: NDArray[np.float64], t: float) -> str:
        """Run IHRCF / ATDA on the frame and update (or initialise) the filter. Returns the reason
        when nothing could be measured ('' otherwise)."""
        p = self.params
        if frame.corners is None:
            return frame.corners_reason
        offset_state = p.range_offset_sigma > 0 and self.K is not None and p.use_atda_position
        ranges = frame.ranges - self._bias[0] if offset_state else frame.ranges
        # IHRCF up to its 3-D corners, then its own rigid fit
        corners, ihrcf_est = ihrcf_measure(
            frame, ranges, self.touch_pixels, self.rig, self.tag_size, self.max_residual
        )
        ihrcf: PoseEstimate | None = None
        if isinstance(corners, str):
            ihrcf_reason = corners
            corners_ok: IHRCFCorners | None = None
        else:
            corners_ok = corners
            ihrcf = ihrcf_est
            ihrcf_reason = ihrcf.reason
            if ihrcf.valid:
                self._update_range_noise(frame)
            else:
                ihrcf = None
        # ATDA with the filter's prediction as the flip prior
        atda: PoseEstimate | None = None
        atda_reason = "ATDA not used"
        if self.K is not None and (p.use_atda_attitude or p.use_atda_position):
            prior = self._filtered_R_bd(R_wb)
            est = atda_choose(
                atda_frame_candidates(frame, self.K, self.dist, self.tag_size, self.rig),
                prior if prior is not None else self._atda_prior,
            )
            atda_reason = est.reason
            if est.valid:
                atda = est
                self._atda_prior = np.array(est.rotation)
        if ihrcf is None and atda is None:
            return f"IHRCF: {ihrcf_reason}; ATDA: {atda_reason}"

        # a filter whose every measurement was rejected for max_rejections frames has lost track
        for key in ("_att", "_pos"):
            kf = getattr(self, key)
            if kf is not None and kf.rejected_run >= p.max_rejections:
                setattr(self, key, None)
                self._converged = False
                self.diagnostics["reinitialised"].append(key[1:])
        if self._att is None and self._pos is None and ihrcf is None and not p.use_atda_position:
            return f"IHRCF: {ihrcf_reason}"  # nothing to start from before a position is measured
        new_att = self._att is None
        if self._att is None:
            self._att = _Imm(
                (math.pi, p.init_rate_sigma, p.init_angle_accel_sigma),
                [np.full(3, d) for d in p.angle_drift],
                self._q_white_att,
                p.model_switch_time,
                t,
                angles=True,
                q_value=self._q_value_att,
            )
        new_pos = self._pos is None and (ihrcf is not None or (atda is not None and p.use_atda_position))
        if new_pos:
            leak = GRAVITY * p.imu_attitude_walk  # gravity leak of the IMU's tilt wander, horizontal
            self._pos = _Imm(
                (10.0, p.init_velocity_sigma, p.init_accel_sigma),
                [np.array([math.hypot(d, leak), math.hypot(d, leak), d]) for d in p.accel_drift],
                self._q_white_pos,
                p.model_switch_time,
                t,
            )
        sigma_r = self.range_sigma

        def apply(kf: _Imm, blocks: list[_Measurement], new: bool) -> int:
            """Sequential updates (the first block of a new filter is not gated); accepted count."""
            n = 0
            for i, m in enumerate(blocks):
                gate = None if (new and i == 0) else self._gate[m.rows[1] - m.rows[0]]
                ok, d2 = kf.update(m.z, m.rows, m.R, gate)
                self.diagnostics["accepted" if ok else "rejected"].append((m.name, round(d2, 3)))
                n += ok
            return n

        # 1. attitude: ATDA (roll, pitch, yaw) and IHRCF's tilt; a new filter starts from IHRCF
        #    (no flip ambiguity) with its yaw
        att: list[_Measurement] = []
        if atda is not None and p.use_atda_attitude:
            att.append(self._atda_attitude(atda, R_wb))
        if ihrcf is not None and corners_ok is not None:
            m = self._ihrcf_attitude(ihrcf, corners_ok, R_wb, sigma_r, yaw=new_att or not p.refit)
            att.insert(0, m) if new_att else att.append(m)
        att_ok = apply(self._att, att, new_att)
        # 2. refit with the updated normal, then IHRCF's yaw and position; ATDA's position
        pos: list[_Measurement] = []
        if ihrcf is not None and corners_ok is not None:
            refit = self._refit(corners_ok, ranges, R_wb) if p.refit else None
            if refit is not None:
                if not new_att:
                    att_ok += apply(self._att, [self._refit_yaw(refit, sigma_r, R_wb)], False)
                pos.append(self._refit_position(refit, corners_ok, R_wb, sigma_r))
            else:
                pos.append(self._ihrcf_position(ihrcf, corners_ok, R_wb, sigma_r))
            if offset_state and atda is not None:
                self._update_range_offset(refit if refit is not None else ihrcf, corners_ok, atda)
        if atda is not None and p.use_atda_position:
            pos.append(self._atda_position(atda, R_wb))
        pos_ok = apply(self._pos, pos, new_pos) if self._pos is not None else 0

        for kf, tried, ok in ((self._att, len(att), att_ok), (self._pos, len(pos), pos_ok)):
            if kf is not None and tried:
                kf.frames += ok > 0
                kf.rejected_run = 0 if ok else kf.rejected_run + 1
                if ok:
                    kf.last_accepted = t
        self.diagnostics["range_sigma"] = sigma_r
        if not (att_ok or pos_ok):
            return "every measurement rejected by the gate"
        return "" if ihrcf is not None else f"IHRCF: {ihrcf_reason}"

    def _cam_point(self, est: PoseEstimate) -> NDArray[np.float64]:
        """The deck origin of a body-frame estimate in the camera frame (m)."""
        return _R_CAM_BODY @ (est.position - self._camera_position)

    def _atda_attitude(self, atda: PoseEstimate, R_wb: NDArray[np.float64]) -> _Measurement:
        p = self.params
        d = self._depth_scale(self._cam_point(atda)[2])
        tilt, yaw = p.atda_tilt_sigma * d * d, p.atda_yaw_sigma * d
        return _Measurement(
            "atda.attitude",
            euler_from_matrix(R_wb @ atda.rotation),
            (0, 3),
            np.diag([tilt**2, tilt**2, yaw**2]),
        )

    def _ihrcf_yaw_var(self, depth: float, sigma_r: float) -> float:
        p = self.params
        return (p.ihrcf_yaw_floor * self._depth_scale(depth)) ** 2 + (
            p.ihrcf_yaw_per_range * sigma_r / max(depth, 1e-3)
        ) ** 2

    def _ihrcf_attitude(
        self, ihrcf: PoseEstimate, corners: IHRCFCorners, R_wb: NDArray[np.float64], sigma_r: float, yaw: bool
    ) -> _Measurement:
        p = self.params
        _, tilt_var = _plane_covariance(self.rig.sensor_xy_cam[corners.ranges_used], sigma_r)
        tilt_var += p.ihrcf_tilt_floor**2
        euler = euler_from_matrix(R_wb @ ihrcf.rotation)
        if yaw:
            yaw_var = self._ihrcf_yaw_var(self._cam_point(ihrcf)[2], sigma_r)
            return _Measurement("ihrcf.attitude", euler, (0, 3), np.diag([tilt_var, tilt_var, yaw_var]))
        return _Measurement("ihrcf.tilt", euler[:2], (0, 2), np.diag([tilt_var, tilt_var]))

    def _ihrcf_position(
        self, ihrcf: PoseEstimate, corners: IHRCFCorners, R_wb: NDArray[np.float64], sigma_r: float
    ) -> _Measurement:
        p = self.params
        X = self._cam_point(ihrcf)
        xy = self.rig.sensor_xy_cam[corners.ranges_used]
        C, tilt_var = _plane_covariance(xy, sigma_r)
        g = np.array([1.0, X[0], X[1]])
        depth_var = float(g @ C @ g)
        lever = (self.tag_size / 2) ** 2 / max(X[2], 1e-3)
        lat = (p.ihrcf_lateral_floor * self._depth_scale(X[2])) ** 2 + lever**2 * tilt_var
        C = _ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return _Measurement("ihrcf.position", R_wb @ ihrcf.position, (0, 3), C)

    def _refit(
        self, corners: IHRCFCorners, ranges: NDArray[np.float64], R_wb: NDArray[np.float64]
    ) -> PoseEstimate | None:
        """IHRCF's corner rays intersected with the filter's deck plane through the touch points."""
        R_bd = self._filtered_R_bd(R_wb)
        if R_bd is None:
            return None
        n = -(_R_CAM_BODY @ R_bd[:, 2])  # deck normal in the camera frame, into the deck (n_z > 0)
        used = corners.ranges_used
        c = float((self.rig.sensor_xy_cam[used] @ n[:2] + ranges[used] * n[2]).sum()) / int(used.sum())
        along = corners.corners_cam @ n
        if not (along.min() > 1e-6 and c > 0):
            return None
        est = ihrcf_fit(
            corners.corners_cam * (c / along)[:, None], self.rig, self.tag_size, self.max_residual
        )
        return est if est.valid else None

    def _refit_yaw(self, refit: PoseEstimate, sigma_r: float, R_wb: NDArray[np.float64]) -> _Measurement:
        var = self._ihrcf_yaw_var(self._cam_point(refit)[2], sigma_r)
        return _Measurement(
            "ihrcf.yaw", euler_from_matrix(R_wb @ refit.rotation)[2:], (2, 3), np.array([[var]])
        )

    def _refit_position(
        self, refit: PoseEstimate, corners: IHRCFCorners, R_wb: NDArray[np.float64], sigma_r: float
    ) -> _Measurement:
        p = self.params
        assert self._att is not None
        X = self._cam_point(refit)
        xy = self.rig.sensor_xy_cam[corners.ranges_used]
        dxy = X[:2] - xy.sum(axis=0) / len(xy)
        rho2 = float(dxy @ dxy)
        tilt_var = float(max(self._att.value_cov[0, 0], self._att.value_cov[1, 1]))
        depth_var = sigma_r**2 / len(xy) + rho2 * tilt_var
        lat = (p.ihrcf_lateral_floor * self._depth_scale(X[2])) ** 2
        C = _ray_covariance(X, R_wb @ R_BODY_CAM, depth_var, lat, p.ihrcf_depth_floor**2)
        return _Measurement("ihrcf.position", R_wb @ refit.position, (0, 3), C)

    def _atda_position(self, atda: PoseEstimate, R_wb: NDArray[np.float64]) -> _Measurement:
        p = self.params
        X = self._cam_point(atda)
        d = self._depth_scale(X[2])
        dv, lat = (p.atda_depth_sigma * d * d) ** 2, (p.atda_lateral_sigma * d) ** 2
        return _Measurement(
            "atda.position", R_wb @ atda.position, (0, 3), _ray_covariance(X, R_wb @ R_BODY_CAM, dv, lat, 0.0)
        )

    def _output(self, R_wb: NDArray[np.float64], reason: str) -> PoseEstimate:
        p = self.params
        if self._att is None or self._pos is None:
            what = "not initialised" if self._att is None else "position not initialised"
            return PoseEstimate.invalid(f"{what}: {reason or 'no measurement yet'}")
        pos_sigma, ang_sigma = self._pos.value_sigma(), self._att.value_sigma()
        self.diagnostics.update(position_sigma=pos_sigma, angle_sigma=ang_sigma)
        if not self._converged:  # latched: afterwards only the timeouts end the validity
            frames = min(self._pos.frames, self._att.frames)
            why = ""
            if frames < p.min_updates:
                why = f"{frames}/{p.min_updates} updates"
            elif pos_sigma > p.valid_position_sigma:
                why = f"position sigma {pos_sigma:.3g} m > {p.valid_position_sigma:.3g} m"
            elif ang_sigma > p.valid_angle_sigma:
                limit = math.degrees(p.valid_angle_sigma)
                why = f"angle sigma {math.degrees(ang_sigma):.3g} deg > {limit:.3g} deg"
            if why:
                return PoseEstimate.invalid(f"converging: {why}" + (f" ({reason})" if reason else ""))
            self._converged = True
        R_bd = R_wb.T @ matrix_from_euler(*self._att.x[0:3])
        p_bd = R_wb.T @ self._pos.x[0:3]
        return PoseEstimate.from_body_pose(R_bd, p_bd, math.sqrt(float(np.trace(self._pos.value_cov))))
