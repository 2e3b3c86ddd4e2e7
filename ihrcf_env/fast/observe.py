"""The estimator stage and the normalised observation of the landing tasks, for one environment:
the JAX twin of :class:`~ihrcf_env.wrappers.landing_obs.LandingObservation` (with its
:class:`~ihrcf_env.wrappers.estimator_stage.EstimatorStage`) over a
:class:`~ihrcf_env.fast.raw.RawReading`.

- :func:`observe_params` (host-side, once per configuration): the layout (the same ``obs_slices``,
  scales and bounds as the wrapper's, from :mod:`ihrcf_env.core.landing_layout`), the calibration's
  estimators (IHRCF, ATDA, the IMU-fused filter, in the configuration's order) and the stage's
  timing (control period, camera latency, the ToF's own clock).
- :func:`observe_init` / :func:`observe_reset`: the state of an episode's start (a pytree).
- :func:`observe`: one control step's observation (float32, clipped into the Box), the next state
  and each estimate's :class:`EstimateInfo` (what the env's ``info`` shows).

The stage's branches are masks: a camera frame is *new* when its ``camera_age`` is 0 (no camera
latency) or when ``camera_frame`` changed (a latency: the frame is stamped with its exposure, the
IMU sample of the step nearest the exposure and the ranges measured nearest it, and the fused
filter predicts it to the arrival); the estimators run every step and their results are taken
only for a new frame, else the last estimates are shown again. With the fused filter, IHRCF's
estimate is made in the filter's own IHRCF call (one call over the pair of range readings). An
estimate's block holds its last valid values (heading frame of the current step) while it is
invalid and its age grows.

``deck_forecast`` appends the forecast block of :mod:`ihrcf_env.fast.forecast_feed` (the port of
the wrapper's :class:`~ihrcf_env.wrappers.forecast_feed.ForecastFeed`), fed by the fused estimate
shown on each new frame; its refit runs on every step under ``vmap`` (a fixed cost per env and
step), so it is opt-in as on the PyBullet env. Parameters are static: close over them
(``jax.jit(functools.partial(observe, params))``) or pass them as a static argument
(``jax.jit(observe, static_argnums=0)``: they compare by identity). Frames as
:mod:`ihrcf_env.wrappers.landing_obs` (body, heading frame from the IMU's attitude); SI units.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, tree_util

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import FusedParams
from ihrcf_env.core.estimators import fused_reasons as fr
from ihrcf_env.core.estimators import reasons as rs
from ihrcf_env.core.estimators.cv_lm import MAX_ITER as MAX_LM_ITER
from ihrcf_env.core.estimators.registry import BUILTIN_ESTIMATORS
from ihrcf_env.core.landing_layout import (
    FORECAST,
    GROUND_TRUTH,
    MAX_AGE,
    MOTION,
    POSITION_SCALE,
    RATE_SCALE,
    forecast_fields,
    landing_blocks,
)
from ihrcf_env.core.layout import build_layout
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.fast import forecast_feed as ff
from ihrcf_env.fast import fused as fu
from ihrcf_env.fast.detector import STATUS_NAMES
from ihrcf_env.fast.fused_blocks import imu_sample
from ihrcf_env.fast.ihrcf import IHRCFSetup, ihrcf, ihrcf_setup
from ihrcf_env.fast.linalg3 import matrix_from_euler
from ihrcf_env.fast.pnp import pnp_candidates, pnp_choose
from ihrcf_env.fast.raw import RawReading, Truth
from ihrcf_env.fast.table import touch_table

__all__ = [
    "NO_FRAME_STATUS",
    "EstimateInfo",
    "ObserveParams",
    "ObserveState",
    "observe",
    "observe_init",
    "observe_params",
    "observe_reset",
    "reason_text",
]

#: ``EstimateInfo.status`` of a frame shown before the first camera frame arrived (a latency).
NO_FRAME_STATUS = -1
#: The reason of an estimate made before the first camera frame arrived.
NO_FRAME_YET = "no camera frame yet"
#: Tolerance (ticks) of a sensor clock's sample instants (as the simulator's sample clocks).
TICK_EPS = 1e-6
#: The tasks whose observation this module builds.
TASKS = ("landing-v1", "landing-v2")


@dataclasses.dataclass(frozen=True, eq=False)
class ObserveParams:
    """Static configuration of :func:`observe` (:func:`observe_params`; compares by identity).

    Attributes:
        names: the estimators, in the observation's order (a subset of ``ihrcf``, ``atda``,
            ``fused``).
        slices, scales, low, high: the layout (as the wrapper's ``obs_slices``, ``obs_scales`` and
            Box bounds); ``size`` its length.
        max_range: the ToF's max range (m, the ranges' scale).
        privileged, deck_motion: the optional blocks.
        substeps, dt: physics ticks per control step and the tick (s).
        latency: the camera latency (s); ``counted``: frames are counted (``latency > 0``).
        history: control steps of IMU samples and ranges kept for a late frame.
        tof_ticks: physics ticks per ToF sample (its own clock), or None (read every step).
        ihrcf: IHRCF's setup; ``K`` (3, 3), ``dist`` (5,), ``tag_size`` (m), ``camera_position``
            (3,; body, m): ATDA's camera; ``fused``: the fused filter's setup (None without it).
        atda: ATDA's candidates are needed (``atda`` listed, or the fused filter uses them).
        max_residual: IHRCF's rigid-fit bound (m), for the reason text.
        fused_params: the fused filter's parameters (None without it).
        lm_iterations: the LM steps polishing each of ATDA's IPPE poses.
        forecast: the forecast block's constants (``deck_forecast``; None without it).
    """

    names: tuple[str, ...]
    slices: dict[str, slice]
    scales: dict[str, float]
    low: np.ndarray
    high: np.ndarray
    size: int
    max_range: float
    privileged: bool
    deck_motion: bool
    substeps: int
    dt: float
    latency: float
    counted: bool
    history: int
    tof_ticks: float | None
    ihrcf: IHRCFSetup
    K: np.ndarray
    dist: np.ndarray
    tag_size: float
    camera_position: np.ndarray
    fused: fu.FusedSetup | None
    atda: bool
    max_residual: float
    fused_params: FusedParams | None
    lm_iterations: int = MAX_LM_ITER
    forecast: ff.FeedParams | None = None


class EstimateInfo(NamedTuple):
    """One estimate as the env's ``info`` shows it (the estimate shown this step).

    ``valid``; ``code``: the reason code (IHRCF and ATDA: :data:`ihrcf_env.core.estimators.reasons.REASONS`;
    fused: the outer code of :data:`ihrcf_env.core.estimators.fused_reasons.OUTER`), 0 when valid;
    ``position`` (3,) m and ``euler`` (3,) rad of the deck in the body frame (zeros when invalid);
    ``age`` (s) since the exposure of the frame behind it (NaN before the first frame);
    ``residual``; ``status``: the frame's tag status (``tag_status``; :data:`NO_FRAME_STATUS`
    before the first frame); the numbers of the reason text (``fit_rms`` m; fused: ``outer_num``,
    ``inner``, ``inner_num``, ``ihrcf_code``, ``ihrcf_rms``, ``atda_code``): :func:`reason_text`.
    """

    valid: Array
    code: Array
    position: Array
    euler: Array
    age: Array
    residual: Array
    status: Array
    fit_rms: Array
    outer_num: Array
    inner: Array
    inner_num: Array
    ihrcf_code: Array
    ihrcf_rms: Array
    atda_code: Array


class ObserveState(NamedTuple):
    """The stage's and the observation's state (one environment).

    ``steps``: control steps since the episode's start (-1 before its first observation);
    ``has_last``: estimates have been made; ``frame_count``: the ``camera_frame`` of the last frame
    estimated; ``frame_time``: the time (s) of the frame behind the estimates shown (NaN: none);
    ``hist_*``: the last ``history`` steps' time (s), IMU sample, ranges, their validity and time
    (s), oldest first, ``hist_filled`` where kept; ``last``: the estimates shown (one
    :class:`EstimateInfo` per estimator, ``age`` unused); ``held_block`` (E, 8), ``held_time`` (E,) s,
    ``has_held`` (E,): each estimator's last valid block and the time of its frame; ``prior``,
    ``has_prior``: ATDA's flip prior; ``fused``: the fused filter's state (None without it);
    ``motion`` (6,): the deck-motion block shown; ``feed``, ``forecast``: the forecaster's state
    and its last output (``deck_forecast``; None without it).
    """

    steps: Array
    has_last: Array
    frame_count: Array
    frame_time: Array
    hist_time: Array
    hist_quaternion: Array
    hist_angular_velocity: Array
    hist_specific_force: Array
    hist_ranges: Array
    hist_ranges_valid: Array
    hist_ranges_time: Array
    hist_filled: Array
    last: tuple[EstimateInfo, ...]
    held_block: Array
    held_time: Array
    has_held: Array
    prior: Array
    has_prior: Array
    fused: fu.FusedState | None
    motion: Array
    feed: ff.FeedState | None = None
    forecast: ff.FeedOutput | None = None


def _rig(calibration: Calibration) -> SensorRig:
    r = calibration.rig
    cp = r["camera_position"]
    return SensorRig(float(r["a"]), float(r["theta"]), (float(cp[0]), float(cp[1]), float(cp[2])))


def observe_params(config: DeckLandingConfig, lm_iterations: int = MAX_LM_ITER) -> ObserveParams:
    """The :class:`ObserveParams` of a resolved landing config (:func:`ihrcf_env.make_config`):
    its observation options, the calibration it names and the world's timing; ``lm_iterations``
    the LM steps that polish each IPPE pose (always all of them: the default is cv2's limit, with
    which the poses are cv2's; fewer are cheaper and stop short of cv2's converged pose where
    it needs more steps). ValueError naming
    what this observation cannot build (a raw observation, an estimator other than
    ``ihrcf``/``atda``/``fused``, the camera's image output, the fused filter's
    ``range_only_update``)."""
    if not isinstance(config, DeckLandingConfig):
        raise TypeError(
            f"config must be a DeckLandingConfig (ihrcf_env.make_config), got {type(config).__name__}"
        )
    if isinstance(lm_iterations, bool) or not isinstance(lm_iterations, int) or not 0 <= lm_iterations <= 100:
        raise ValueError(f"lm_iterations must be an int in [0, 100], got {lm_iterations!r}")
    if config.task_name not in TASKS:
        raise ValueError(
            f"config: the observation of task {config.task_name!r} is not built here (tasks: {TASKS})"
        )
    obs, world = config.observation, config.world
    if obs.raw or obs.calibration is None:
        raise ValueError("config.observation: a raw observation has no flat observation (raw=True)")
    names = tuple(obs.estimators)
    available = sorted(BUILTIN_ESTIMATORS)  # the JAX observation ports every built-in estimator
    unknown = [n for n in names if n not in available]
    if unknown:
        raise ValueError(
            f"estimators: {unknown} not available in the JAX observation (available: {available})"
        )
    if world.camera is None:
        raise ValueError("camera: the landing observation needs a camera")
    if world.camera_output != "corners":
        raise ValueError(
            f"camera_output: the JAX observation reads the tag's corners, got {world.camera_output!r}"
        )
    cal = obs.calibration
    rig = _rig(cal)
    tag = float(world.deck.tag_size)
    K = np.asarray(cal.K, dtype=np.float64).reshape(3, 3)
    dist = np.zeros(5)
    if cal.dist is not None:
        d = np.asarray(cal.dist, dtype=np.float64).ravel()
        dist[: d.size] = d
    fused = None
    if "fused" in names:
        fused = fu.fused_setup(cal.tables, rig, tag, K, dist, obs.max_residual, obs.fused_params)
        ih = fused.ihrcf
        fp = fused.consts.params
        fused_atda = fp.use_atda_attitude or fp.use_atda_position
    else:
        ih = ihrcf_setup(touch_table(cal.tables), rig, tag, obs.max_residual)
        fp, fused_atda = None, False
    max_range = float(world.tof.max_range)
    feed = None
    forecast_block = None
    if obs.deck_forecast is not None:
        feed = ff.feed_params(obs.deck_forecast, config.task.deck.length_scale)
        forecast_block = (FORECAST, forecast_fields(feed.forecast.horizons.size))
    lay = build_layout(landing_blocks(names, max_range, obs.privileged, obs.deck_motion, forecast_block))
    latency = float(world.camera.latency)
    span = latency + world.camera_every / world.control_hz
    rate = world.tof.rate_hz
    return ObserveParams(
        names=names,
        slices=lay.slices,
        scales=lay.scales,
        low=lay.low,
        high=lay.high,
        size=lay.size,
        max_range=max_range,
        privileged=bool(obs.privileged),
        deck_motion=bool(obs.deck_motion),
        substeps=int(world.substeps),
        dt=1.0 / world.physics_hz,
        latency=latency,
        counted=latency > 0,
        history=math.ceil(span * world.control_hz) + 2,
        tof_ticks=None if rate is None else world.physics_hz / float(rate),
        ihrcf=ih,
        K=K,
        dist=dist,
        tag_size=tag,
        camera_position=np.asarray(rig.camera_position_array, dtype=np.float64),
        fused=fused,
        atda="atda" in names or fused_atda,
        max_residual=float(obs.max_residual),
        fused_params=fp,
        lm_iterations=lm_iterations,
        forecast=feed,
    )


def _float() -> Any:
    return jnp.result_type(float)


def _blank_info() -> EstimateInfo:
    f = _float()
    z = jnp.zeros((), f)
    i = jnp.zeros((), jnp.int32)
    return EstimateInfo(
        jnp.zeros((), bool), jnp.full((), rs.NOT_DETECTED, jnp.int32), jnp.zeros(3, f), jnp.zeros(3, f),
        jnp.full((), jnp.nan, f), z, jnp.full((), NO_FRAME_STATUS, jnp.int32), z, jnp.zeros(2, f),
        i, z, i, z, i,
    )  # fmt: skip


def observe_init(params: ObserveParams) -> ObserveState:
    """The state of an episode's start (before its first observation)."""
    f = _float()
    k, e = params.history, len(params.names)
    return ObserveState(
        steps=jnp.full((), -1, jnp.int32),
        has_last=jnp.zeros((), bool),
        frame_count=jnp.full((), -1, jnp.int32),
        frame_time=jnp.full((), jnp.nan, f),
        hist_time=jnp.zeros(k, f),
        hist_quaternion=jnp.tile(jnp.array([0.0, 0.0, 0.0, 1.0], f), (k, 1)),
        hist_angular_velocity=jnp.zeros((k, 3), f),
        hist_specific_force=jnp.zeros((k, 3), f),
        hist_ranges=jnp.zeros((k, 4), f),
        hist_ranges_valid=jnp.zeros((k, 4), bool),
        hist_ranges_time=jnp.zeros(k, f),
        hist_filled=jnp.zeros(k, bool),
        last=tuple(_blank_info() for _ in params.names),
        held_block=jnp.zeros((e, 8), f),
        held_time=jnp.zeros(e, f),
        has_held=jnp.zeros(e, bool),
        prior=jnp.eye(3, dtype=f),
        has_prior=jnp.zeros((), bool),
        fused=None if params.fused is None else fu.fused_init(params.fused),
        motion=jnp.zeros(6, f),
        feed=None if params.forecast is None else ff.feed_init(params.forecast, f),
        forecast=None if params.forecast is None else _blank_forecast(params.forecast),
    )


def _blank_forecast(fp: ff.FeedParams) -> ff.FeedOutput:
    f = _float()
    h = fp.forecast.horizons.size
    z = jnp.zeros((), f)
    return ff.FeedOutput(
        jnp.zeros(fp.size, f), jnp.zeros((h, 4), f), jnp.zeros((h, 4), f), z, jnp.zeros((), bool)
    )


def observe_reset(params: ObserveParams, state: ObserveState, mask: Array | bool = True) -> ObserveState:
    """``state`` at an episode's start where ``mask`` (a scalar per environment; default: always),
    unchanged elsewhere."""
    fresh = observe_init(params)
    m = jnp.asarray(mask, bool)
    return tree_util.tree_map(lambda a, b: jnp.where(m, a, b), fresh, state)


def _heading(R_wb: Array) -> tuple[Array, Array]:
    """(R_lb, R_lw) of ``R_wb`` (as :func:`ihrcf_env.wrappers.landing_obs.heading_rotation`)."""
    yaw = jnp.arctan2(R_wb[1, 0], R_wb[0, 0])
    c, s = jnp.cos(yaw), jnp.sin(yaw)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    R_lw = jnp.stack([jnp.stack([c, s, zero]), jnp.stack([-s, c, zero]), jnp.stack([zero, zero, one])])
    return R_lw @ R_wb, R_lw


def _pose_block(R_lb: Array, position: Array, R_bd: Array) -> Array:
    """Scaled (position 3, normal 3, cos/sin yaw 2) of a deck pose in the body frame."""
    p = R_lb @ position / POSITION_SCALE
    R_ld = R_lb @ R_bd
    yaw = jnp.arctan2(R_ld[1, 0], R_ld[0, 0])
    return jnp.concatenate([p, R_ld[:, 2], jnp.stack([jnp.cos(yaw), jnp.sin(yaw)])])


def _push(arr: Array, value: Array) -> Array:
    return jnp.concatenate([arr[1:], jnp.asarray(value, arr.dtype)[None]], axis=0)


def _pose_info(pose: Any, status: Array) -> EstimateInfo:
    f = _float()
    z = jnp.zeros((), f)
    i = jnp.zeros((), jnp.int32)
    return EstimateInfo(
        pose.valid, pose.code.astype(jnp.int32), pose.position, pose.euler, jnp.full((), jnp.nan, f),
        pose.residual, status, pose.fit_rms, jnp.zeros(2, f), i, z, i, z, i,
    )  # fmt: skip


def _fused_info(out: fu.FusedOutput, status: Array) -> EstimateInfo:
    f = _float()
    return EstimateInfo(
        out.valid, out.outer.astype(jnp.int32), out.position, out.euler, jnp.full((), jnp.nan, f),
        out.residual, status, jnp.zeros((), f), out.outer_num, out.inner.astype(jnp.int32), out.inner_num,
        out.ihrcf_code.astype(jnp.int32), out.ihrcf_rms, out.atda_code.astype(jnp.int32),
    )  # fmt: skip


def _select(m: Array, a: Any, b: Any) -> Any:
    return tree_util.tree_map(lambda x, y: jnp.where(m, x, y), a, b)


def observe(
    params: ObserveParams, state: ObserveState, raw: RawReading, truth: Truth
) -> tuple[Array, ObserveState, dict[str, EstimateInfo]]:
    """One control step: the observation (float32, ``params.size``), the next state and each
    estimator's :class:`EstimateInfo` (name -> info), from the step's ``raw`` reading and its
    ``truth`` (read only by the ``privileged`` block). Call it for the reset's reading too (after
    :func:`observe_reset`), then once per control step."""
    p, st = params, state
    f = _float()
    steps = st.steps + 1
    now = (steps * p.substeps).astype(f) * p.dt
    first = ~st.has_last
    q = jnp.asarray(raw.imu_quaternion, f)
    w = jnp.asarray(raw.imu_angular_velocity, f)
    sf = jnp.asarray(raw.imu_linear_acceleration, f)
    ranges = jnp.asarray(raw.ranges, f)
    rvalid = jnp.asarray(raw.ranges_valid).astype(bool)
    corners = jnp.asarray(raw.tag_corners, f)
    age = jnp.asarray(raw.camera_age, f).reshape(())
    nan = jnp.full((), jnp.nan, f)

    # the frame: is it new, when was it exposed, which IMU sample and ranges go with it
    hist: tuple[Array, ...] = (
        st.hist_time, st.hist_quaternion, st.hist_angular_velocity, st.hist_specific_force,
        st.hist_ranges, st.hist_ranges_valid, st.hist_ranges_time, st.hist_filled,
    )  # fmt: skip
    late = jnp.zeros((), bool)
    no_frame = jnp.zeros((), bool)
    frame_count = st.frame_count
    exposure = now
    q_f, w_f, f_f, r_f, v_f, rt_f = q, w, sf, ranges, rvalid, nan
    if p.counted:
        if p.tof_ticks is None:
            r_time = now
        else:
            tick = steps * p.substeps
            k = jnp.floor((tick + TICK_EPS) / p.tof_ticks)
            r_time = jnp.ceil(k * p.tof_ticks - TICK_EPS) * p.dt
        values: tuple[Array, ...] = (now, q, w, sf, ranges, rvalid, r_time, jnp.ones((), bool))
        hist = tuple(_push(a, v) for a, v in zip(hist, values, strict=True))
        n = jnp.asarray(raw.camera_frame).reshape(()).astype(jnp.int32)
        fresh = first | (n != st.frame_count)
        frame_count = n
        has_exposure = fresh & (n > 0)
        exposure = jnp.round((now - age) / p.dt) * p.dt
        late = has_exposure & (exposure < now)
        no_frame = fresh & ~has_exposure
        ht, hq, hw, hf, hr, hv, hrt, filled = hist
        at = jnp.argmin(jnp.where(filled, jnp.abs(ht - exposure), jnp.inf))
        near = jnp.argmin(jnp.where(filled, jnp.abs(hrt - exposure), jnp.inf))
        q_f = jnp.where(late, hq[at], q)
        w_f = jnp.where(late, hw[at], w)
        f_f = jnp.where(late, hf[at], sf)
        r_f = jnp.where(late, hr[near], ranges)
        v_f = jnp.where(late, hv[near], rvalid)
        rt_f = jnp.where(late, hrt[near], nan)
    else:
        fresh = first | (age == 0.0)
    t_frame = jnp.where(late, exposure, now)
    detected = jnp.asarray(raw.tag_detected).astype(bool) & ~no_frame
    status = jnp.where(
        no_frame, NO_FRAME_STATUS, jnp.where(detected, 0, jnp.asarray(raw.tag_status).astype(jnp.int32))
    )
    frame_time = jnp.where(fresh, jnp.where(no_frame, nan, t_frame), st.frame_time)

    # the estimators (every step; taken for a new frame)
    new: dict[str, EstimateInfo] = {}
    cands = None
    if p.atda:
        cands = pnp_candidates(
            corners,
            detected,
            jnp.asarray(p.K),
            jnp.asarray(p.dist),
            p.tag_size,
            jnp.asarray(p.camera_position),
            p.lm_iterations,
        )
    prior, has_prior = st.prior, st.has_prior
    fused_state = st.fused
    if "fused" in p.names:
        assert p.fused is not None and st.fused is not None
        frame = fu.FusedFrame(
            t_frame, detected, corners, r_f, v_f, rt_f, jnp.ones((), bool), q_f, w_f, f_f,
            jnp.where(late, now, nan), late, q, w, sf,
        )  # fmt: skip
        f_cands = cands if p.fused.K is not None else None
        if "ihrcf" in p.names:  # IHRCF's estimate in the filter's IHRCF call
            fused_state, ih_pose = fu.fused_update_with_ihrcf(
                p.fused, st.fused, frame, fresh, f_cands, r_f, v_f, detected
            )
            new["ihrcf"] = _pose_info(ih_pose, status)
        else:
            fused_state = fu.fused_update(p.fused, st.fused, frame, fresh, f_cands)
        new["fused"] = _fused_info(fused_state.out, status)
    for name in p.names:
        if name == "ihrcf":
            if name not in new:
                new[name] = _pose_info(ihrcf(corners, r_f, v_f, detected, p.ihrcf), status)
        elif name == "atda":
            assert cands is not None
            pose = pnp_choose(cands, st.prior, st.has_prior)
            took = fresh & detected & pose.valid
            prior = jnp.where(took, pose.rotation, st.prior)
            has_prior = st.has_prior | took
            new[name] = _pose_info(pose, status)
    shown = tuple(_select(fresh, new[name], st.last[i]) for i, name in enumerate(p.names))

    # the observation
    R_wb, _, _ = imu_sample(q, sf, w)
    R_lb, R_lw = _heading(R_wb)
    R_wb = R_lw.T @ R_lb
    sl, sc = p.slices, p.scales
    out = jnp.zeros(p.size, f)

    def put(o: Array, key: str, v: Array) -> Array:
        s = sl[key]
        return o.at[s.start : s.stop].set(v)

    out = put(out, "ranges", ranges / sc["ranges"])
    out = put(out, "ranges_valid", rvalid.astype(f))
    out = put(out, "imu.up", R_wb[2, :])
    out = put(out, "imu.angular_velocity", w / RATE_SCALE)
    out = put(out, "imu.linear_acceleration", sf / GRAVITY)
    out = put(out, "nav_velocity", R_lw @ jnp.asarray(raw.nav_velocity, f))
    ages = now - frame_time
    # the estimates' blocks in one call over the estimators
    valid = jnp.stack([est.valid for est in shown])
    blocks = jax.vmap(lambda x, e: _pose_block(R_lb, x, matrix_from_euler(e)))(
        jnp.stack([est.position for est in shown]), jnp.stack([est.euler for est in shown])
    )
    held_block = jnp.where(valid[:, None], blocks, st.held_block)
    held_time = jnp.where(valid, now - ages, st.held_time)
    has_held = st.has_held | valid
    infos: dict[str, EstimateInfo] = {}
    for i, name in enumerate(p.names):
        est = shown[i]
        hb, ht, hh = held_block[i], held_time[i], has_held[i]
        s0, s1 = sl[f"{name}.position"].start, sl[f"{name}.valid"].start
        out = out.at[s0:s1].set(jnp.where(hh, hb, 0.0))
        out = put(out, f"{name}.age", jnp.where(hh, (now - ht) / sc[f"{name}.age"], MAX_AGE)[None])
        out = put(out, f"{name}.valid", est.valid.astype(f)[None])
        infos[name] = est._replace(age=ages)
    motion = st.motion
    if p.deck_motion:
        assert fused_state is not None
        o = fused_state.out
        motion = jnp.where(o.motion_valid, jnp.concatenate([R_lw @ o.velocity, R_lw @ o.normal_rate]), motion)
        out = put(out, MOTION, motion)
    feed, forecast = st.feed, st.forecast
    if p.forecast is not None:
        assert st.feed is not None
        nav_vz = jnp.asarray(raw.nav_velocity, f)[2]
        feed, forecast = ff.feed_step(
            p.forecast, st.feed, now, nav_vz, fresh, shown[p.names.index("fused")], R_lb, R_lw
        )
        out = put(out, FORECAST, forecast.block)
    if p.privileged:
        R_true, _, _ = imu_sample(
            jnp.asarray(truth.drone_quaternion_world, f), jnp.zeros(3, f), jnp.zeros(3, f)
        )
        R_lb_t, R_lw_t = _heading(R_true)
        truth_block = _pose_block(
            R_lb_t, jnp.asarray(truth.deck_position_body, f), jnp.asarray(truth.deck_rotation_body, f)
        )
        vel = R_lw_t @ jnp.asarray(truth.relative_velocity, f)
        wind = R_lw_t @ jnp.asarray(truth.wind_velocity, f)
        out = put(out, GROUND_TRUTH, jnp.concatenate([truth_block, vel, wind]))
    out = jnp.clip(jnp.where(jnp.isnan(out), 0.0, out), jnp.asarray(p.low, f), jnp.asarray(p.high, f))
    ht, hq, hw, hf, hr, hv, hrt, filled = hist
    state = ObserveState(
        steps=steps,
        has_last=jnp.ones((), bool),
        frame_count=frame_count,
        frame_time=frame_time,
        hist_time=ht,
        hist_quaternion=hq,
        hist_angular_velocity=hw,
        hist_specific_force=hf,
        hist_ranges=hr,
        hist_ranges_valid=hv,
        hist_ranges_time=hrt,
        hist_filled=filled,
        last=shown,
        held_block=held_block,
        held_time=held_time,
        has_held=has_held,
        prior=prior,
        has_prior=has_prior,
        fused=fused_state,
        motion=motion,
        feed=feed,
        forecast=forecast,
    )
    return out.astype(jnp.float32), state, infos


def _status_reason(status: int) -> str:
    if status == NO_FRAME_STATUS:
        return NO_FRAME_YET
    return STATUS_NAMES[status] if 0 < status < len(STATUS_NAMES) else "tag not detected"


def reason_text(params: ObserveParams, name: str, info: EstimateInfo) -> str:
    """The reason text of one environment's estimate ``info`` of estimator ``name`` ('' when
    valid), as the env's ``info[f"{name}_reason"]`` writes it (host-side; arrays of one env)."""
    if bool(np.asarray(info.valid)):
        return ""
    code = int(np.asarray(info.code))
    corners = _status_reason(int(np.asarray(info.status)))
    if name != "fused":
        if code == rs.FIT_RESIDUAL:
            return rs.REASONS[code].format(
                rms=float(np.asarray(info.fit_rms)), max_residual=params.max_residual
            )
        return corners if code == rs.NOT_DETECTED else rs.REASONS[code]
    assert params.fused_params is not None
    ic = int(np.asarray(info.inner))
    a_code = int(np.asarray(info.atda_code))
    h_code = int(np.asarray(info.ihrcf_code))
    if h_code == rs.FIT_RESIDUAL:
        h_text = rs.REASONS[h_code].format(
            rms=float(np.asarray(info.ihrcf_rms)), max_residual=params.max_residual
        )
    else:
        h_text = rs.REASONS[h_code]
    inner = fr.INNER[ic].format(
        corners=corners,
        t=float(np.asarray(info.inner_num)),
        timeout=params.fused_params.lost_timeout,
        ihrcf=h_text if ic in (fr.BOTH_FAILED, fr.IHRCF_FAILED) else "",
        atda="ATDA not used" if a_code == fr.ATDA_NOT_USED else rs.REASONS[a_code],
    )
    if code in (fr.NOT_INITIALISED, fr.POSITION_NOT_INITIALISED):
        return fr.OUTER[code].format(inner=inner or "no measurement yet")
    a, b = (float(x) for x in np.asarray(info.outer_num))
    text = fr.OUTER[code].format(a=a, b=b)
    if code in (fr.CONVERGING_UPDATES, fr.CONVERGING_POSITION, fr.CONVERGING_ANGLE) and inner:
        text += f" ({inner})"
    return text
