"""The IMU-fused deck-pose filter (:class:`~ihrcf_env.core.estimators.fused.FusedEstimator`) of N
envs at once: :class:`BatchFused`.

Row i follows the single filter fed env i's frames: every branch of
:meth:`FusedEstimator.update` (time checks, bad IMU samples, timeouts, the IMM prediction, IHRCF
and ATDA with the filter's flip prior, the gated sequential blocks in the same order, the
rejection and numerical resets, the delay compensation, the convergence latch) is a row
selection; an env not stepped (``active`` False: a held camera frame) keeps its state and its
last output. The measurement work is :mod:`~ihrcf_env.core.batch.fused_measure`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.stats import chi2

from ihrcf_env.core.batch import fused_result as fr
from ihrcf_env.core.batch.fused_blocks import BlocksBatch
from ihrcf_env.core.batch.fused_frames import BatchFrames
from ihrcf_env.core.batch.fused_measure import MeasureParts, measure
from ihrcf_env.core.batch.fused_result import BatchFusedOutput
from ihrcf_env.core.batch.geometry import euler_batch, matrix_from_euler_batch
from ihrcf_env.core.batch.imm import BatchImm
from ihrcf_env.core.batch.pnp import PnPCandidates
from ihrcf_env.core.batch.tables import BatchTable
from ihrcf_env.core.calibration.tables import RangePixelTable
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators.fused_params import FusedParams
from ihrcf_env.core.estimators.ihrcf import TouchPixels
from ihrcf_env.core.frames import as_array
from ihrcf_env.core.rig import SensorRig, tag_corners_deck

F64 = NDArray[np.float64]
_G_WORLD = np.array([0.0, 0.0, -GRAVITY])


def imu_batch(q: F64, f: F64, w: F64) -> tuple[F64, F64, NDArray[np.int8]]:
    """:func:`~ihrcf_env.core.estimators.fused_delay.imu_sample` per row: R_wb (n, 3, 3), the
    drone's acceleration in the world (n, 3) m/s^2, and 0 / ``IMU_NONFINITE`` / ``IMU_ZERO``."""
    with np.errstate(all="ignore"):
        qq = np.einsum("ni,ni->n", q, q)
        total = qq + np.einsum("ni,ni->n", f, f) + np.einsum("ni,ni->n", w, w)
        code = np.where(~np.isfinite(total), fr.IMU_NONFINITE, np.where(qq < 1e-12, fr.IMU_ZERO, 0))
        ok = code == 0
        qn = np.where(ok[:, None], q, [0.0, 0.0, 0.0, 1.0])
        x, y, z, s = (qn / np.sqrt(np.einsum("ni,ni->n", qn, qn))[:, None]).T
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * s), 2 * (x * z + y * s)], -1),
            np.stack([2 * (x * y + z * s), 1 - 2 * (x * x + z * z), 2 * (y * z - x * s)], -1),
            np.stack([2 * (x * z - y * s), 2 * (y * z + x * s), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )
    fo = np.where(ok[:, None], f, 0.0)
    return R, np.einsum("nij,nj->ni", R, fo) + _G_WORLD, code.astype(np.int8)


def _q_tilt(walk2: float, r: F64) -> F64:
    """The IMU tilt wander's noise on relative positions r (n, 3): ``walk2 (|r|^2 I - r r^T)``."""
    return walk2 * (np.einsum("ni,ni->n", r, r)[:, None, None] * np.eye(3) - r[:, :, None] * r[:, None, :])


class BatchFused:
    """N :class:`~ihrcf_env.core.estimators.fused.FusedEstimator` s (arguments as its, plus ``n``);
    ``touch_pixels``: a :class:`RangePixelTable`, a :class:`BatchTable` or a single-frame table."""

    def __init__(
        self,
        n: int,
        touch_pixels: RangePixelTable | BatchTable | TouchPixels,
        rig: SensorRig,
        tag_size: float,
        K: ArrayLike | None = None,
        dist: ArrayLike | None = None,
        max_residual: float = 0.01,
        params: FusedParams | None = None,
    ) -> None:
        tag_corners_deck(tag_size)
        if not (math.isfinite(max_residual) and max_residual > 0):
            raise ValueError(f"max_residual must be positive (m), got {max_residual!r}")
        if params is not None and not isinstance(params, FusedParams):
            raise TypeError(f"params must be a FusedParams, got {type(params).__name__}")
        self.n = int(n)
        self.touch_pixels = touch_pixels
        #: a RangePixelTable evaluated as a BatchTable; any other table as given (see batch_table)
        self.table: BatchTable | TouchPixels = (
            BatchTable(touch_pixels) if isinstance(touch_pixels, RangePixelTable) else touch_pixels
        )
        self.rig = rig
        self.tag_size = float(tag_size)
        self.K = None if K is None else as_array(K, (3, 3), "K").copy()
        self.dist = None if dist is None else np.asarray(dist, dtype=np.float64).ravel().copy()
        self.max_residual = float(max_residual)
        self.params = p = params if params is not None else FusedParams()
        if p.deck_model != "kinematic":
            raise ValueError(
                f"FusedParams.deck_model={p.deck_model!r} is not supported by the batched fused filter"
            )
        self.blocks = BlocksBatch(p, rig, self.tag_size, self.max_residual)
        self.gate = {k: float(chi2.ppf(p.gate_probability, k)) for k in (1, 2, 3)}
        walk2 = p.imu_attitude_walk**2
        leak = GRAVITY * p.imu_attitude_walk
        self.pos = BatchImm(
            n,
            (10.0, p.init_velocity_sigma, p.init_accel_sigma),
            [np.array([math.hypot(d, leak), math.hypot(d, leak), d]) for d in p.accel_drift],
            np.full(3, p.accel_noise),
            p.model_switch_time,
        )
        self.att = BatchImm(
            n,
            (math.pi, p.init_rate_sigma, p.init_angle_accel_sigma),
            [np.full(3, d) for d in p.angle_drift],
            np.full(3, p.angle_accel_noise),
            p.model_switch_time,
            angles=True,
            q_value=np.diag([walk2, walk2, 0.0]),
        )
        self.pos_ahead, self.att_ahead = self.pos.copy(), self.att.copy()
        A = np.column_stack([np.ones(4), rig.sensor_xy_cam])
        self.residual_direction = np.linalg.svd(A)[0][:, 3].copy()
        self.time = np.zeros(self.n)
        self.has_time = np.zeros(self.n, dtype=bool)
        self.R_wb = np.tile(np.eye(3), (self.n, 1, 1))
        self.a_world = np.full((self.n, 3), np.nan)
        self.log_var = np.zeros(self.n)
        self.var_weight = np.ones(self.n)
        self.atda_prior = np.tile(np.eye(3), (self.n, 1, 1))
        self.has_prior = np.zeros(self.n, dtype=bool)
        self.bias = np.zeros((self.n, 2))
        self.bias_P = np.zeros((self.n, 2, 2))
        self.converged = np.zeros(self.n, dtype=bool)
        self.has_ahead = np.zeros(self.n, dtype=bool)
        self._out: dict[str, NDArray] = {}
        self._corners_reason = [""] * self.n
        self.reset()

    # -- state ---------------------------------------------------------------------------------
    def reset(self, mask: ArrayLike | None = None) -> None:
        """Forget everything in the rows of ``mask`` (N,) bool (default: all), as
        :meth:`FusedEstimator.reset`; their output turns invalid (not initialised)."""
        m = np.ones(self.n, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
        p = self.params
        for kf in (self.pos, self.att, self.pos_ahead, self.att_ahead):
            kf.drop(m)
        self.has_time[m] = False
        self.R_wb[m] = np.eye(3)
        self.a_world[m] = np.nan
        self.log_var[m] = 2.0 * math.log(p.tof_sigma)
        self.var_weight[m] = 1.0
        self.atda_prior[m] = np.eye(3)
        self.has_prior[m] = False
        self.bias[m] = 0.0
        self.bias_P[m] = np.diag([p.range_offset_sigma**2, p.atda_depth_bias_sigma**2])
        self.converged[m] = False
        self.has_ahead[m] = False
        out = self._out
        if not out:
            n = self.n
            out.update(
                position=np.zeros((n, 3)), euler=np.zeros((n, 3)), rotation=np.tile(np.eye(3), (n, 1, 1)),
                valid=np.zeros(n, bool), residual=np.zeros(n), velocity=np.zeros((n, 3)),
                normal_rate=np.zeros((n, 3)), motion_valid=np.zeros(n, bool), frame_time=np.full(n, np.nan),
                outer=np.full(n, fr.NOT_INITIALISED, np.int8), outer_num=np.zeros((n, 2)),
                inner=np.zeros(n, np.int8), inner_num=np.zeros(n), ihrcf_code=np.zeros(n, np.int8),
                ihrcf_rms=np.zeros(n), atda_code=np.zeros(n, np.int8),
            )  # fmt: skip
        for key, arr in out.items():
            arr[m] = np.eye(3) if key == "rotation" else (np.nan if key == "frame_time" else 0)
        out["outer"][m] = fr.NOT_INITIALISED
        for k in np.flatnonzero(m):
            self._corners_reason[k] = ""

    @property
    def range_sigma(self) -> F64:
        """Current range-noise estimates (N,), m."""
        return np.exp(0.5 * self.log_var)

    def motion(self, horizon: float = 0.01) -> tuple[F64, F64, NDArray[np.bool_]]:
        """:meth:`FusedEstimator.motion` per row: velocity (N, 3) m/s, normal rate (N, 3) 1/s and
        the rows where it is defined (zeros elsewhere)."""
        return self._motion(np.arange(self.n), horizon)

    def _motion(self, rows: NDArray[np.intp], horizon: float = 0.01) -> tuple[F64, F64, NDArray[np.bool_]]:
        vel, rate = np.zeros((len(rows), 3)), np.zeros((len(rows), 3))
        ok = np.zeros(len(rows), dtype=bool)
        for ahead in (False, True):
            sel = self.has_ahead[rows] == ahead
            pos, att = (self.pos_ahead, self.att_ahead) if ahead else (self.pos, self.att)
            sel &= self.converged[rows] & pos.alive[rows] & att.alive[rows]
            i = rows[sel]
            if i.size == 0:
                continue
            xa = att.x(i)
            up = matrix_from_euler_batch(xa[:, 0:3] + horizon * xa[:, 3:6])[:, :, 2]
            down = matrix_from_euler_batch(xa[:, 0:3] - horizon * xa[:, 3:6])[:, :, 2]
            vel[sel], rate[sel], ok[sel] = pos.x(i)[:, 3:6], (up - down) / (2.0 * horizon), True
        return vel, rate, ok

    # -- one step ------------------------------------------------------------------------------
    def update(
        self, frames: BatchFrames, active: ArrayLike | None = None, atda: PnPCandidates | None = None
    ) -> BatchFusedOutput:
        """Fuse the frames of the ``active`` rows (N,) bool (default all), as
        :meth:`FusedEstimator.update` of each; ``atda``: ATDA's candidates of the N frames (default:
        computed by :func:`~ihrcf_env.core.batch.pnp.pnp_candidates`). Returns every row's output."""
        p, n = self.params, self.n
        if len(frames) != n:
            raise ValueError(f"frames must have {n} rows, got {len(frames)}")
        act = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        outer = np.zeros(n, np.int8)
        outer_num = np.zeros((n, 2))
        self.has_ahead[act] = False
        # time (NaN: one nominal interval after the last frame); backwards: ignored
        t = np.where(
            np.isnan(frames.time), np.where(self.has_time, self.time + p.nominal_dt, 0.0), frames.time
        )
        back = act & self.has_time & (t < self.time)
        outer[back] = fr.TIME_BACKWARDS
        outer_num[back] = np.column_stack([t, self.time])[back]
        go = act & ~back
        # the IMU sample (none: the last attitude, no acceleration)
        R_imu, a_imu, code = imu_batch(frames.quaternion, frames.specific_force, frames.angular_velocity)
        imu_p = frames.imu_present
        bad = go & imu_p & (code != 0)
        outer[bad] = code[bad]
        go &= ~bad
        good = go & imu_p
        self.R_wb[good] = R_imu[good]
        R_wb = self.R_wb.copy()
        a_world = np.where(imu_p[:, None], a_imu, np.nan)
        dt = np.where(self.has_time, t - self.time, 0.0)
        self.time[go], self.has_time[go] = t[go], True
        # timeouts, then the prediction on the IMU
        lost, lost_t = np.zeros(n, np.int8), np.zeros(n)
        for kf, code_k in ((self.att, fr.NO_ATT), (self.pos, fr.NO_POS)):
            since = t - kf.last_accepted
            m = go & kf.alive & (since > p.lost_timeout)
            lost[m] = np.where(frames.detected[m], code_k, fr.TAG_LOST)
            lost_t[m] = since[m]
            kf.drop(m)
            self.converged[m] = False
        self.has_prior[go & ~self.att.alive & ~self.pos.alive] = False
        u = a_world
        if p.accel_hold == "trapezoid":
            u = np.where(np.isfinite(self.a_world), 0.5 * (a_world + self.a_world), a_world)
        self.a_world[go] = a_world[go]
        i = np.flatnonzero(go & self.pos.alive)
        if i.size:
            self.pos.predict(i, dt[i], -u[i], _q_tilt(p.imu_attitude_walk**2, self.pos.x(i)[:, 0:3]))
        i = np.flatnonzero(go & self.att.alive)
        if i.size:
            self.att.predict(i, dt[i])

        parts = measure(self, frames, go, t, R_wb, atda)
        inner = np.where(lost != 0, lost, parts.inner).astype(np.int8)
        inner_num = np.where(lost != 0, lost_t, 0.0)
        # numerical failure: both filters dropped
        rows = np.flatnonzero(go)
        broken = np.zeros(n, dtype=bool)
        for kf in (self.pos, self.att):
            broken[rows] |= kf.alive[rows] & ~kf.finite(rows)
        for kf in (self.pos, self.att):
            kf.drop(broken)
        self.converged[broken] = False
        self.has_prior[broken] = False
        outer[broken] = fr.NUMERICAL
        go &= ~broken
        # a late frame: copies of the filters predicted to its arrival
        late = go & np.isfinite(frames.arrival_time) & (frames.arrival_time > t)
        R_arr, a_arr, code = imu_batch(
            frames.arrival_quaternion, frames.arrival_specific_force, frames.arrival_angular_velocity
        )
        arr_p = frames.arrival_present
        bad = late & arr_p & (code != 0)
        outer[bad] = np.where(code[bad] == fr.IMU_ZERO, fr.ARRIVAL_ZERO, fr.ARRIVAL_NONFINITE)
        late &= ~bad
        go &= ~bad
        R_now = np.where(arr_p[:, None, None], R_arr, R_wb)
        a_now = np.where(arr_p[:, None], a_arr, a_world)
        i = np.flatnonzero(late)
        if i.size:
            self._predict_ahead(i, frames.arrival_time[i] - t[i], a_world[i], a_now[i])
        R_out = np.where(late[:, None, None], R_now, R_wb)
        self._output(np.flatnonzero(go & ~late), R_out, self.pos, self.att, outer, outer_num)
        self._output(i, R_out, self.pos_ahead, self.att_ahead, outer, outer_num)
        return self._store(act, frames, outer, outer_num, inner, inner_num, parts)

    def _predict_ahead(self, i: NDArray[np.intp], dt: F64, a_then: F64, a_now: F64) -> None:
        p = self.params
        u = a_now
        if p.accel_hold == "trapezoid":
            u = np.where(np.isfinite(a_then), 0.5 * (a_now + a_then), a_now)
        self.has_ahead[i] = True
        for kf, ahead in ((self.pos, self.pos_ahead), (self.att, self.att_ahead)):
            ahead.assign(i, kf)
        j = i[self.pos.alive[i]]
        if j.size:
            sel = self.pos.alive[i]
            q = _q_tilt(p.imu_attitude_walk**2, self.pos.x(j)[:, 0:3])
            self.pos_ahead.predict(j, dt[sel], -u[sel], q)
        j = i[self.att.alive[i]]
        if j.size:
            self.att_ahead.predict(j, dt[self.att.alive[i]])

    def _output(
        self, i: NDArray[np.intp], R_wb: F64, pos: BatchImm, att: BatchImm, outer: NDArray[np.int8], num: F64
    ) -> None:
        """The filters' pose in the body frame of ``R_wb`` (rows ``i``), or why not (in ``outer``)."""
        p, o = self.params, self._out
        if i.size == 0:
            return
        outer[i[~att.alive[i]]] = fr.NOT_INITIALISED
        outer[i[att.alive[i] & ~pos.alive[i]]] = fr.POSITION_NOT_INITIALISED
        i = i[att.alive[i] & pos.alive[i]]
        if i.size == 0:
            return
        pos_sigma, ang_sigma = pos.value_sigma(i), att.value_sigma(i)
        frames = np.minimum(pos.frames[i], att.frames[i])
        new = ~self.converged[i]
        c1 = new & (frames < p.min_updates)
        c2 = new & ~c1 & (pos_sigma > p.valid_position_sigma)
        c3 = new & ~c1 & ~c2 & (ang_sigma > p.valid_angle_sigma)
        outer[i[c1]] = fr.CONVERGING_UPDATES
        num[i[c1]] = np.column_stack([frames[c1], np.full(c1.sum(), p.min_updates)])
        outer[i[c2]] = fr.CONVERGING_POSITION
        num[i[c2]] = np.column_stack([pos_sigma[c2], np.full(c2.sum(), p.valid_position_sigma)])
        outer[i[c3]] = fr.CONVERGING_ANGLE
        num[i[c3]] = np.column_stack(
            [np.degrees(ang_sigma[c3]), np.full(c3.sum(), math.degrees(p.valid_angle_sigma))]
        )
        ok = ~(c1 | c2 | c3)
        i = i[ok]
        self.converged[i] = True
        R = R_wb[i]
        R_bd = R.transpose(0, 2, 1) @ matrix_from_euler_batch(att.x(i)[:, 0:3])
        o["rotation"][i] = R_bd
        o["euler"][i] = euler_batch(R_bd)
        o["position"][i] = np.einsum("nji,nj->ni", R, pos.x(i)[:, 0:3])
        o["residual"][i] = np.sqrt(np.trace(pos.value_cov(i), axis1=1, axis2=2))

    def _store(
        self,
        act: NDArray[np.bool_],
        frames: BatchFrames,
        outer: NDArray[np.int8],
        outer_num: F64,
        inner: NDArray[np.int8],
        inner_num: F64,
        parts: MeasureParts,
    ) -> BatchFusedOutput:
        """Rows ``act`` of the held outputs set from this step; the output of every row."""
        o = self._out
        valid = act & (outer == fr.OK)
        invalid = act & ~valid
        o["valid"][act] = valid[act]
        o["position"][invalid], o["euler"][invalid] = 0.0, 0.0
        o["rotation"][invalid], o["residual"][invalid] = np.eye(3), 0.0
        o["outer"][act], o["outer_num"][act] = outer[act], outer_num[act]
        o["inner"][act], o["inner_num"][act] = inner[act], inner_num[act]
        o["ihrcf_code"][act], o["ihrcf_rms"][act] = parts.ihrcf_code[act], parts.ihrcf_rms[act]
        o["atda_code"][act] = parts.atda_code[act]
        o["frame_time"][act] = frames.time[act]
        rows = np.flatnonzero(act)
        vel, rate, ok = self._motion(rows)
        o["velocity"][rows], o["normal_rate"][rows], o["motion_valid"][rows] = vel, rate, ok
        for k in rows:
            self._corners_reason[k] = frames.corners_reason[k]
        return BatchFusedOutput(
            **{k: v.copy() for k, v in o.items()},
            corners_reason=tuple(self._corners_reason),
            params=self.params,
            max_residual=self.max_residual,
        )


__all__ = [
    "BatchFused",
    "imu_batch",
]
