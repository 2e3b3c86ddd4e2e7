"""The fused deck-pose estimator: IHRCF + ATDA's attitude + the IMU + a causal Kalman filter.

:class:`FusedEstimator` maps each frame's IHRCF / ATDA estimates with the IMU attitude into a
gravity-aligned filter frame, smooths the relative position and the deck attitude there with
interacting multiple models of a kinematic Kalman filter (:mod:`~ihrcf_env.core.estimators.imm`)
fed by the accelerometer, and maps back with the current IMU attitude. The range noise is estimated
online from the plane-fit residual of the four ranges, so the same filter trusts IHRCF's tilt with
exact ranges and ATDA's with noisy ones. It uses only what a real drone logs (a
:class:`~ihrcf_env.core.estimators.base.SensorFrame` per camera frame); pure numpy / scipy plus
the package's pure estimators. Parameters: :class:`~ihrcf_env.core.estimators.fused_params.FusedParams`;
measurement blocks: :mod:`~ihrcf_env.core.estimators.fused_measurements`; the design, step by step,
is described in ``docs/fused.md``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators.atda import atda_choose, atda_frame_candidates
from ihrcf_env.core.estimators.base import ImuSample, PoseEstimate, SensorFrame
from ihrcf_env.core.estimators.fused_delay import imu_sample, predict_ahead
from ihrcf_env.core.estimators.fused_measurements import Measurement, MeasurementBlocks, plane_covariance
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.estimators.fused_ranges import ranges_distance, ranges_plane, ranges_tilt
from ihrcf_env.core.estimators.ihrcf import IHRCFCorners, TouchPixels, ihrcf_measure
from ihrcf_env.core.estimators.imm import Imm
from ihrcf_env.core.estimators.imm_deck import DeckImm
from ihrcf_env.core.frames import R_BODY_CAM, as_array, matrix_from_euler
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

__all__ = ["FusedEstimator", "FusedParams"]

#: E[ln X] for X ~ chi-square(1): the bias of the log-domain average of one-dof variance samples.
_LOG_CHI2_1_MEAN = -1.2703628454614782


class FusedEstimator:
    """IHRCF (+ ATDA's attitude) + IMU + causal Kalman filter, as a
    :class:`~ihrcf_env.core.estimators.base.DeckPoseSource` (design in ``docs/fused.md``).

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
        self.params = params if params is not None else FusedParams()
        p = self.params
        self._blocks = MeasurementBlocks(p, rig, self.tag_size, self.max_residual)
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
        self._pos: Imm | None = None
        self._att: Imm | None = None
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
        #: the filters predicted to the last frame's arrival time (a frame that arrived late), or None
        self._ahead: tuple[Imm | None, Imm | None] | None = None
        #: the oscillator banks set by :meth:`set_deck_oscillation` (position, attitude) or None
        self._oscillation: dict[str, tuple[tuple[float, ...], NDArray[np.float64]]] = {}
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
        pos, att = self._ahead if self._ahead is not None else (self._pos, self._att)
        if not self._converged or pos is None or att is None:
            return None
        x_att = att.x
        angles, rates = x_att[0:3], x_att[3:6]
        ahead = matrix_from_euler(*(angles + horizon * rates))[:, 2]
        behind = matrix_from_euler(*(angles - horizon * rates))[:, 2]
        return np.array(pos.x[3:6]), (ahead - behind) / (2.0 * horizon)

    def set_deck_oscillation(
        self, heave: tuple[float, float] | None = None, tilt: tuple[float, float] | None = None
    ) -> None:
        """Centre the oscillator banks of ``deck_model="oscillator"`` on identified deck dynamics
        (for example :meth:`~ihrcf_env.core.forecast.DeckForecaster.oscillation`): ``heave`` =
        (period s, standard deviation m) of the deck's vertical motion, ``tilt`` = (period s,
        standard deviation rad) of its roll and pitch. The bank of each filter becomes
        ``deck_periods`` scaled to that median period, and the oscillators' stationary
        acceleration on the vertical axis (position) or on roll and pitch (attitude) ``std * (2 pi
        / period)^2``; the other axes keep the parameters'. Applies to the live filters and to
        those created later, until :meth:`reset`. ValueError with another deck model or a period
        outside [0.1, 60] s or a negative or non-finite standard deviation (naming the argument)."""
        p = self.params
        if p.deck_model != "oscillator":
            raise ValueError(f"set_deck_oscillation needs deck_model='oscillator', got {p.deck_model!r}")
        bank = np.asarray(p.deck_periods, dtype=np.float64)
        for key, value, sigma, axes in (
            ("heave", heave, p.deck_accel_sigma, (2,)),
            ("tilt", tilt, p.deck_angle_accel_sigma, (0, 1)),
        ):
            if value is None:
                continue
            period, std = (float(v) for v in value)
            if not (math.isfinite(period) and 0.1 <= period <= 60.0):
                raise ValueError(f"{key}: period must be in [0.1, 60] s, got {period!r}")
            if not (math.isfinite(std) and std >= 0.0):
                raise ValueError(f"{key}: standard deviation must be finite and >= 0, got {std!r}")
            accel = np.full(3, sigma)
            accel[list(axes)] = std * (2.0 * math.pi / period) ** 2
            periods = tuple(float(x) for x in bank * (period / float(np.median(bank))))
            self._oscillation[key] = (periods, accel)
            kf = self._pos if key == "heave" else self._att
            if isinstance(kf, DeckImm):
                kf.set_oscillators(periods, accel)

    def update(self, frame: SensorFrame) -> PoseEstimate:
        """Fuse ``frame`` (time non-decreasing) and return the filtered deck pose in the body frame.

        Delays: the filter runs on the frames' (exposure) ``time``, each frame fused at its own time
        with the IMU sample of that time; ranges measured at another ``ranges_time`` are moved to
        ``time`` along the filter's relative velocity. A frame that arrived later
        (``arrival_time``) is then predicted to its arrival on the IMU (``arrival_imu``): the
        output is the pose at arrival, in the body frame of then."""
        p = self.params
        self.diagnostics = {"accepted": [], "rejected": [], "reinitialised": []}
        self._ahead = None
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
        arrival = frame.arrival_time
        if math.isnan(arrival) or arrival <= t:
            return self._output(R_wb, lost_reason or reason)
        # a late frame: the output of copies of the filters predicted to its arrival
        now = imu_sample(frame.arrival_imu) if frame.arrival_imu is not None else (R_wb, a_world)
        if isinstance(now, str):
            return PoseEstimate.invalid(f"arrival {now}")
        self._ahead = predict_ahead(self._pos, self._att, p, arrival - t, a_world, now[1])
        return self._output(now[0], lost_reason or reason, *self._ahead)

    # -- internals ----------------------------------------------------------------------------
    def _imu(self, imu: ImuSample | None) -> tuple[NDArray[np.float64], NDArray[np.float64] | None] | str:
        """(R_wb, drone acceleration in the world or None) of a sample, or why the frame is ignored."""
        if imu is None:  # no IMU: the last attitude (identity before any), no acceleration input
            return (self._R_wb if self._R_wb is not None else np.eye(3)), None
        out = imu_sample(imu)
        if not isinstance(out, str):
            self._R_wb = out[0]
        return out

    def _new_att(self, t: float) -> Imm:
        """A new attitude filter at time ``t`` (s), of the parameters' deck model."""
        p = self.params
        sigmas = (math.pi, p.init_rate_sigma, p.init_angle_accel_sigma)
        drifts = [np.full(3, d) for d in p.angle_drift]
        if p.deck_model == "oscillator":
            periods, accel = self._oscillation.get(
                "tilt", (p.deck_periods, np.full(3, p.deck_angle_accel_sigma))
            )
            return DeckImm(
                sigmas, drifts, self._q_white_att, p.model_switch_time, t, periods, p.deck_damping,
                accel, np.full(3, p.deck_oscillator_drift), angles=True, q_value=self._q_value_att,
            )  # fmt: skip
        return Imm(
            sigmas, drifts, self._q_white_att, p.model_switch_time, t, angles=True, q_value=self._q_value_att
        )

    def _new_pos(self, t: float) -> Imm:
        """A new position filter at time ``t`` (s), of the parameters' deck model."""
        p = self.params
        leak = GRAVITY * p.imu_attitude_walk  # gravity leak of the IMU's tilt wander, horizontal
        sigmas = (10.0, p.init_velocity_sigma, p.init_accel_sigma)
        drifts = [np.array([math.hypot(d, leak), math.hypot(d, leak), d]) for d in p.accel_drift]
        if p.deck_model == "oscillator":
            d = p.deck_oscillator_drift
            periods, accel = self._oscillation.get("heave", (p.deck_periods, np.full(3, p.deck_accel_sigma)))
            return DeckImm(
                sigmas, drifts, self._q_white_pos, p.model_switch_time, t, periods, p.deck_damping,
                accel, np.array([math.hypot(d, leak), math.hypot(d, leak), d]),
            )  # fmt: skip
        return Imm(sigmas, drifts, self._q_white_pos, p.model_switch_time, t)

    def _drop(self) -> None:
        self._pos = None
        self._att = None
        self._converged = False
        self._atda_prior = None

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
        X, Y = self._blocks.cam_point(ihrcf), self._blocks.cam_point(atda)
        d = self._blocks.depth_scale(Y[2])
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
        offset_state = p.range_offset_sigma > 0 and self.K is not None and p.use_atda_position
        ranges = frame.ranges - self._bias[0] if offset_state else frame.ranges
        shift = t - frame.ranges_time  # ranges measured at another time: moved to t (NaN: at t)
        if shift != 0.0 and not math.isnan(shift) and self._pos is not None:
            v_cam = R_BODY_CAM.T @ (R_wb.T @ self._pos.x[3:6])  # depth rate of the deck, m/s
            ranges = ranges + float(v_cam[2]) * shift
        if frame.corners is None:
            if p.range_only_update:
                self._range_only(frame, ranges, R_wb, t)
            return frame.corners_reason
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
            if p.range_only_update:
                self._range_only(frame, ranges, R_wb, t)
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
            self._att = self._new_att(t)
        new_pos = self._pos is None and (ihrcf is not None or (atda is not None and p.use_atda_position))
        if new_pos:
            self._pos = self._new_pos(t)
        sigma_r = self.range_sigma

        def apply(kf: Imm, blocks: list[Measurement], new: bool) -> int:
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
        att: list[Measurement] = []
        if atda is not None and p.use_atda_attitude:
            att.append(self._blocks.atda_attitude(atda, R_wb))
        if ihrcf is not None and corners_ok is not None:
            m = self._blocks.ihrcf_attitude(ihrcf, corners_ok, R_wb, sigma_r, yaw=new_att or not p.refit)
            att.insert(0, m) if new_att else att.append(m)
        att_ok = apply(self._att, att, new_att)
        # 2. refit with the updated normal, then IHRCF's yaw and position; ATDA's position
        pos: list[Measurement] = []
        if ihrcf is not None and corners_ok is not None:
            R_bd = self._filtered_R_bd(R_wb) if p.refit else None
            refit = self._blocks.refit(corners_ok, ranges, R_bd) if R_bd is not None else None
            if refit is not None:
                if not new_att:
                    att_ok += apply(self._att, [self._blocks.refit_yaw(refit, sigma_r, R_wb)], False)
                C = self._att.value_cov
                tilt_var = float(max(C[0, 0], C[1, 1]))
                pos.append(self._blocks.refit_position(refit, corners_ok, R_wb, sigma_r, tilt_var))
            else:
                pos.append(self._blocks.ihrcf_position(ihrcf, corners_ok, R_wb, sigma_r))
            if offset_state and atda is not None:
                self._update_range_offset(refit if refit is not None else ihrcf, corners_ok, atda)
        if atda is not None and p.use_atda_position:
            pos.append(self._blocks.atda_position(atda, R_wb))
        pos_ok = apply(self._pos, pos, new_pos) if self._pos is not None else 0
        if (
            p.reseed_agreeing
            and self._pos is not None
            and not pos_ok
            and len(pos) >= 2
            and self._pos.rejected_run
        ):
            pos_ok = self._reseed(self._pos, pos[0], pos[1])

        for kf, tried, ok in ((self._att, len(att), att_ok), (self._pos, len(pos), pos_ok)):
            if kf is not None and tried:
                kf.frames += ok > 0
                kf.rejected_run = 0 if ok else kf.rejected_run + 1
                if ok:
                    kf.last_accepted = t
        if p.drop_lost_track:  # a filter that lost track is not coasted on
            for key in ("_att", "_pos"):
                kf = getattr(self, key)
                if kf is not None and kf.rejected_run >= p.max_rejections:
                    setattr(self, key, None)
                    self._converged = False
                    self.diagnostics["reinitialised"].append(key[1:])
        self.diagnostics["range_sigma"] = sigma_r
        if not (att_ok or pos_ok):
            return "every measurement rejected by the gate"
        return "" if ihrcf is not None else f"IHRCF: {ihrcf_reason}"

    def _reseed(self, kf: Imm, a: Measurement, b: Measurement) -> int:
        """``reseed_agreeing``: both position measurements ``a`` and ``b`` of the position filter
        ``kf`` were rejected, for a second frame in a row; if they agree with each other within the
        gate, the prediction is what is wrong: the position restarts at their combination (the
        rates kept, looser). Returns 1 if it did, else 0."""
        d = a.z - b.z
        if float(d @ np.linalg.solve(a.R + b.R, d)) > self._gate[3]:
            return 0
        info_a, info_b = np.linalg.inv(a.R), np.linalg.inv(b.R)
        R = np.linalg.inv(info_a + info_b)
        R = 0.5 * (R + R.T)
        kf.reseed(R @ (info_a @ a.z + info_b @ b.z), R, self.params.init_velocity_sigma**2)
        self.diagnostics["reinitialised"].append("pos (reseeded)")
        return 1

    def _range_only(
        self, frame: SensorFrame, ranges: NDArray[np.float64], R_wb: NDArray[np.float64], t: float
    ) -> None:
        """The range-only update (``range_only_update``, a frame without a tag measurement): the
        deck's tilt and its distance along the normal from >= 3 valid ranges on one plane (four:
        their plane-fit residual within the 1-dof gate); lateral position and yaw coast, and the
        counters of the timeouts and of the rejections are left alone."""
        pos, att = self._pos, self._att
        plane = ranges_plane(ranges, frame.ranges_valid, self.rig.sensor_xy_cam)
        if pos is None or att is None or plane is None:
            return
        normal, used = plane
        if used.all():
            self._update_range_noise(frame)
            if float(self._residual_direction @ ranges) ** 2 > self._gate[1] * self.range_sigma**2:
                self.diagnostics["rejected"].append(("ranges.plane", math.inf))
                return
        p, sigma_r = self.params, self.range_sigma
        _, tilt_var = plane_covariance(self.rig.sensor_xy_cam[used], sigma_r)
        tilt_var += p.ihrcf_tilt_floor**2
        z = ranges_tilt(normal, R_wb, float(att.x[2]))
        ok, d2 = att.update(z, (0, 2), np.diag([tilt_var, tilt_var]), self._gate[2])
        self.diagnostics["accepted" if ok else "rejected"].append(("ranges.tilt", round(d2, 3)))
        C = att.value_cov
        R_bd = R_wb.T @ matrix_from_euler(*att.x[0:3])
        zd, h, var = ranges_distance(
            ranges, used, self.rig.sensor_xy_cam, self._blocks.camera_position, R_bd, R_wb,
            pos.x[0:3], sigma_r, float(max(C[0, 0], C[1, 1])), p.ihrcf_depth_floor**2,
        )  # fmt: skip
        ok, d2 = pos.update_along(zd, h, var, self._gate[1])
        self.diagnostics["accepted" if ok else "rejected"].append(("ranges.distance", round(d2, 3)))
        self.diagnostics["lateral_coasting"] = t - pos.last_accepted

    def _output(
        self, R_wb: NDArray[np.float64], reason: str, pos: Imm | None = None, att: Imm | None = None
    ) -> PoseEstimate:
        """The pose of the filters ``pos`` and ``att`` (default: the filters) in the body frame of
        ``R_wb``."""
        p = self.params
        pos = self._pos if pos is None else pos
        att = self._att if att is None else att
        if att is None or pos is None:
            what = "not initialised" if att is None else "position not initialised"
            return PoseEstimate.invalid(f"{what}: {reason or 'no measurement yet'}")
        pos_sigma, ang_sigma = pos.value_sigma(), att.value_sigma()
        self.diagnostics.update(position_sigma=pos_sigma, angle_sigma=ang_sigma)
        if not self._converged:  # latched: afterwards only the timeouts end the validity
            frames = min(pos.frames, att.frames)
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
        R_bd = R_wb.T @ matrix_from_euler(*att.x[0:3])
        p_bd = R_wb.T @ pos.x[0:3]
        return PoseEstimate.from_body_pose(R_bd, p_bd, math.sqrt(float(np.trace(pos.value_cov))))
