"""The landing env's control step in JAX: physics, sensors and task rules of one env, as pure
functions (the functional API of gymnax-style trainers).

* ``reset(key, params) -> (obs, state)``: an episode drawn from ``key``
  (:func:`~ihrcf_env.fast.episode.draw_episode`).
* ``reset_from(episode, key, params) -> (obs, state)``: a given episode (e.g. the PyBullet env's,
  :func:`~ihrcf_env.fast.episode.host_episode`).
* ``step(key, state, action, params) -> (obs, state, reward, done, info)``: one control step with
  its noise drawn from ``key``; a finished episode is followed by a new one drawn from ``key``
  (the returned state and observation are the new episode's, ``done`` is True, ``info`` is the
  finished step's).
* ``step_env(key, state, action, params)``: the same without the reset.
* ``step_with(draws, state, action, params)``: the step with its noise given
  (:class:`~ihrcf_env.fast.state.StepDraws`), as the PyBullet env would draw it.

One control step: the action (4,) in [-1, 1] (clipped) scaled by ``max_velocity`` to the velocity
setpoint; the deck's poses at the period's physics ticks (the profile driven tick by tick, held
once out of the legs' stroke); the wind at each tick; the flight (autopilot on the navigation
estimate, ground effect, wind drag, rigid body, touchdown) one tick at a time; the ToF array on
its sample clock; then the IMU and the camera's frame (detector model, frame dropout, latency) at
the step's end; the raw reading and ground truth (:mod:`ihrcf_env.fast.raw`); the outcome, reward
and termination by the task rules of :mod:`ihrcf_env.tasks`. Everything is per env (no batch
axis): batch with ``jax.vmap`` and compile with ``jax.jit`` outside. The params
(:func:`~ihrcf_env.fast.params.make_params`) are static.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import Array, lax

from ihrcf_env import tasks
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.fast.advance import Flight, advance, angular_velocity_between
from ihrcf_env.fast.autopilot import controller_reset
from ihrcf_env.fast.deck_motion import (
    DeckTrack,
    ShipPhasor,
    deck_pose,
    deck_track,
    ship_phasor,
    ship_phasor_advance,
    ship_pose,
    ship_pose_of_phasor,
    sum_of_sines,
)
from ihrcf_env.fast.dynamics import hover_state, matrix_from_quaternion, quaternion_from_matrix
from ihrcf_env.fast.episode import Episode, draw_episode, host_episode
from ihrcf_env.fast.frames import TICK_EPS, pipe_deliver, pipe_init, pipe_push
from ihrcf_env.fast.imu import READ_DRAWS, ImuState, imu_read, imu_reset
from ihrcf_env.fast.linalg3 import cross, matvec
from ihrcf_env.fast.navigation import NavState, nav_estimate, nav_start, nav_step
from ihrcf_env.fast.params import StepParams
from ihrcf_env.fast.raw import RawReading, Truth
from ihrcf_env.fast.sense import camera_frame, tof_reading
from ihrcf_env.fast.state import EnvState, ReadDraws, StepDraws
from ihrcf_env.fast.wind import WindEpisode, wind_episode, wind_force, wind_velocity

__all__ = [
    "INVALID_ACTION",
    "INVALID_ACTION_NAME",
    "MAX_NAV_VELOCITY",
    "MAX_SENSOR_AGE",
    "StepInfo",
    "draw_reads",
    "draw_step",
    "reset",
    "reset_from",
    "step",
    "step_env",
    "step_with",
    "state_spec",
]

#: Upper bound (s) of ``camera_age`` (the env's).
MAX_SENSOR_AGE = 10.0
#: Bound (m/s) of ``nav_velocity`` (the env's).
MAX_NAV_VELOCITY = 20.0
#: The outcome code of a step given a non-finite action (NaN or inf): the step flies the zero
#: command and the episode ends as a crash (after the codes of :data:`ihrcf_env.tasks.OUTCOME_NAMES`;
#: ``tasks.is_crash`` holds for it). The Gymnasium fronts refuse such an action before stepping.
INVALID_ACTION = len(tasks.OUTCOME_NAMES)
#: The name of :data:`INVALID_ACTION`.
INVALID_ACTION_NAME = "invalid_action"


class StepInfo(NamedTuple):
    """What a step reports beside the observation: the raw reading and truth, the outcome code
    (:data:`ihrcf_env.tasks.OUTCOME_NAMES`), the reward's terms (a ``tasks`` terms NamedTuple),
    the step's touchdown record and the episode time (s)."""

    raw: RawReading
    truth: Truth
    outcome: Array
    terms: Any
    touchdown: tasks.TouchdownState
    time: Array


def _strong(tree: Any) -> Any:
    """``tree`` with every leaf of a fixed (not weak) dtype: a state from ``reset`` and one from
    ``step`` have the same types, so a compiled step never retraces for either."""
    return jax.tree_util.tree_map(lambda x: jnp.asarray(x, dtype=jnp.asarray(x).dtype), tree)


# -- argument checks (at trace time) ---------------------------------------------------------------
def _check_params(params: Any) -> StepParams:
    if not isinstance(params, StepParams):
        raise TypeError(
            f"params must be a StepParams (ihrcf_env.fast.params.make_params), got {type(params).__name__}"
        )
    return params


def _check_key(key: Any, name: str = "key") -> Array:
    if not isinstance(key, jax.Array | np.ndarray):
        raise TypeError(
            f"{name} must be a jax.random key (jax.random.key or PRNGKey), "
            f"got {type(key).__name__} {key!r:.40}"
        )
    k = jnp.asarray(key) if not isinstance(key, jax.Array) else key
    if jnp.issubdtype(k.dtype, jax.dtypes.prng_key):
        if k.shape != ():
            raise ValueError(f"{name} must be one PRNG key (shape ()), got shape {k.shape}")
        return k
    if k.shape != (2,) or k.dtype != jnp.uint32:
        got = f"{k.dtype}{list(k.shape)}"
        raise ValueError(f"{name} must be a jax.random key (a typed key, or uint32 of shape (2,)), got {got}")
    return k


def _check_action(action: Any, p: StepParams) -> tuple[Array, Array]:
    """The action clipped to [-1, 1] in the params' dtype, the zero command where it is not finite,
    and whether it was finite (:data:`INVALID_ACTION`)."""
    if not isinstance(action, jax.Array | np.ndarray | np.number | list | tuple | int | float) or isinstance(
        action, bool
    ):
        raise TypeError(f"action must be 4 real numbers (shape (4,)), got {type(action).__name__}")
    a = jnp.asarray(action) if not isinstance(action, jax.Array) else action
    if a.shape != (4,):
        raise ValueError(f"action must have shape (4,) per env, got {a.shape}")
    if not jnp.issubdtype(a.dtype, jnp.floating) and not jnp.issubdtype(a.dtype, jnp.integer):
        raise TypeError(f"action must be real numbers, got dtype {a.dtype}")
    a = a.astype(p.dtype)
    finite = jnp.all(jnp.isfinite(a))
    return jnp.where(finite, jnp.clip(a, -1.0, 1.0), jnp.zeros_like(a)), finite


def state_spec(params: StepParams) -> EnvState:
    """The shapes and dtypes (``jax.ShapeDtypeStruct`` leaves) of a state of ``params`` in the
    current x64 mode (traced once per params and mode, nothing computed)."""
    p = _check_params(params)
    x64 = jax.dtypes.canonicalize_dtype(np.float64) == np.float64
    cache: dict[bool, EnvState] = p.__dict__.setdefault("_state_specs", {})
    if x64 not in cache:
        # a host-drawn episode: every deck profile has one (the sea state is drawn on the host only)
        with jax.ensure_compile_time_eval():  # numbers, also when called while tracing
            episode = host_episode(p, SeedStreams.from_generator(np.random.default_rng(0)))
        cache[x64] = jax.eval_shape(lambda e, k: reset_from(e, k, p)[1], episode, jax.random.PRNGKey(0))
    return cache[x64]


def _path_text(path: Any) -> str:
    return "".join(f".{k.name}" if hasattr(k, "name") else f"[{getattr(k, 'idx', k)}]" for k in path)


def check_tree(name: str, value: Any, spec: Any, hint: str = "") -> None:
    """TypeError / ValueError naming ``name`` (and the field) when ``value``'s structure, shapes or
    dtypes differ from ``spec``'s (a pytree of ``ShapeDtypeStruct``; checked at trace time)."""
    want = jax.tree_util.tree_structure(spec)
    got = jax.tree_util.tree_structure(value)
    if str(got) != str(want):
        raise TypeError(f"{name}: not a state of these params{hint} (its structure differs: {got} != {want})")
    leaves = jax.tree_util.tree_leaves_with_path(value)
    for (path, leaf), ref in zip(leaves, jax.tree_util.tree_leaves(spec), strict=True):
        shape, dtype = jnp.shape(leaf), jnp.result_type(leaf)
        if shape != ref.shape or dtype != ref.dtype:
            raise ValueError(
                f"{name}{_path_text(path)}: {dtype}{list(shape)}, expected {ref.dtype}{list(ref.shape)}{hint}"
            )


def _check_state(state: Any, p: StepParams) -> EnvState:
    if not isinstance(state, EnvState):
        raise TypeError(f"state must be an EnvState (from reset), got {type(state).__name__}")
    check_tree("state", state, state_spec(p), f" (the params' dtype is {np.dtype(p.dtype).name})")
    return state


# -- deck and wind ---------------------------------------------------------------------------------
def _profile_pose(p: StepParams, ep: Episode, t: Array) -> tuple[Array, Array]:
    if p.deck.kind == "ship":
        assert p.deck.ship is not None
        return ship_pose(t, ep.deck, p.deck.ship)
    return sum_of_sines(t, *ep.deck)


def _deck_next(p: StepParams, ep: Episode, prev: DeckTrack, tick: Array) -> DeckTrack:
    return _deck_at(p, prev, *_profile_pose(p, ep, tick * p.dt + ep.deck_time))


def _deck_at(p: StepParams, prev: DeckTrack, off: Array, rpy: Array) -> DeckTrack:
    d = p.deck
    return deck_track(
        prev, off, rpy, jnp.asarray(d.home_position), jnp.asarray(d.top_joints), jnp.asarray(d.base_joints),
        d.min_leg, d.max_leg, d.half_thickness,
    )  # fmt: skip


def _deck_first(p: StepParams, ep: Episode, tick: Array) -> DeckTrack:
    off, rpy = _profile_pose(p, ep, tick * p.dt + ep.deck_time)
    pos, R = deck_pose(off, rpy, jnp.asarray(p.deck.home_position))
    return DeckTrack(pos, R, pos - R[:, 2] * p.deck.half_thickness, jnp.asarray(False))


def _wind_of(p: StepParams, ep: Episode) -> WindEpisode:
    if p.wind is None:
        z = jnp.zeros(3, p.dtype)
        return WindEpisode(z, jnp.zeros((2, 3), p.dtype), jnp.asarray(False))
    return wind_episode(ep.wind_u[0], ep.wind_u[1], ep.gusts, p.wind)


def _air(p: StepParams, w: WindEpisode, t: Array) -> Array:
    if p.wind is None:
        return jnp.zeros(3, p.dtype)
    return wind_velocity(t, w, p.wind)


def _point_velocity(
    body: Array, q0: Array, q1: Array, body0: Array, dt: float, point: Array
) -> tuple[Array, Array]:
    """(velocity of the deck's material point at ``point``, the plate's linear velocity)."""
    v = (body - body0) / dt
    w = angular_velocity_between(q0, q1, dt)
    return v + cross(w, point - body), v


# -- the step's pieces -----------------------------------------------------------------------------
def _task_state(flight: Flight, deck: DeckTrack, deck_point_velocity: Array) -> tasks.TaskState:
    d = flight.drone
    return tasks.TaskState(
        drone_position=d.position,
        drone_rotation=matrix_from_quaternion(d.quaternion),
        drone_velocity=d.velocity,
        deck_position=deck.position,
        deck_rotation=deck.rotation,
        deck_point_velocity=deck_point_velocity,
    )


def _truth(p: StepParams, s: tasks.TaskState, flight: Flight, deck_quat: Array, wind: Array) -> Truth:
    R = s.drone_rotation
    return Truth(
        drone_position_world=s.drone_position,
        drone_quaternion_world=flight.drone.quaternion,
        deck_position_world=s.deck_position,
        deck_quaternion_world=deck_quat,
        deck_position_body=R.T @ (s.deck_position - s.drone_position),
        deck_rotation_body=R.T @ s.deck_rotation,
        relative_velocity=s.drone_velocity - s.deck_point_velocity,
        wind_velocity=wind,
    )


def _clock_index(p: StepParams, tick: Array) -> Array:
    tps = p.tof.ticks_per_sample
    assert tps is not None
    return jnp.floor((tick + TICK_EPS) / tps).astype(jnp.int32)


def _read_end(
    p: StepParams,
    st: EnvState,
    draws: ReadDraws,
    acceleration: Array,
    tof: tuple[Array, Array],
) -> tuple[EnvState, RawReading]:
    """The readings at the step's end (IMU, camera; the ToF sample given) and the new state."""
    ep, f = st.episode, st.flight
    d = f.drone
    R = matrix_from_quaternion(d.quaternion)
    time = st.tick * p.dt
    imu_state, q, gyro, acc = imu_read(
        p.imu, st.imu, R, d.angular_velocity, acceleration, d.quaternion, draws.imu, p.control_dt
    )
    pipe, frames, bad, started = st.pipe, st.frames, st.drop_bad, st.drop_started
    z42 = jnp.zeros((4, 2), p.dtype)
    corners, status, age = z42, jnp.asarray(1, jnp.int32), jnp.asarray(MAX_SENSOR_AGE, p.dtype)
    if p.camera is not None:
        c = p.camera
        corners, status, bad, started = camera_frame(
            p, ep, d.position, R, d.velocity, d.angular_velocity, st.deck.position, st.deck.rotation,
            draws.cam_normals, draws.cam_uniform, draws.drop_u, bad, started,
        )  # fmt: skip
        if c.latency_ticks > 0:
            pipe = pipe_push(pipe, st.tick, corners, status, jnp.asarray(True))
            due = (pipe.exposed >= 0) & (st.tick - pipe.exposed >= c.latency_ticks - TICK_EPS)
            frames = frames + jnp.sum(due).astype(jnp.int32)
            pipe = pipe_deliver(pipe, st.tick, c.latency_ticks)
            corners, status = pipe.held_corners, pipe.held_status
            age = jnp.where(pipe.held_tick >= 0, time - pipe.held_tick * p.dt, MAX_SENSOR_AGE)
        else:
            frames = frames + 1
            age = jnp.zeros((), p.dtype)
        corners = jnp.clip(corners, -1.0, c.bound)
    nav_v = d.velocity
    if p.nav is not None:
        nav_v = nav_estimate(st.nav, d.position, d.velocity, p.nav)[1]
    raw = RawReading(
        time=time,
        tag_corners=corners,
        tag_detected=status == 0,
        tag_status=status,
        camera_age=jnp.clip(age, 0.0, MAX_SENSOR_AGE),
        camera_frame=frames,
        ranges=jnp.clip(tof[0], 0.0, p.tof.max_range),
        ranges_valid=tof[1],
        imu_quaternion=jnp.clip(q, -1.0, 1.0),
        imu_angular_velocity=jnp.clip(gyro, -50.0, 50.0),
        imu_linear_acceleration=jnp.clip(acc, -200.0, 200.0),
        nav_velocity=jnp.clip(nav_v, -MAX_NAV_VELOCITY, MAX_NAV_VELOCITY),
    )
    new = st._replace(imu=imu_state, pipe=pipe, frames=frames, drop_bad=bad, drop_started=started)
    return new, raw


def _trim(p: StepParams, flight: Flight, deck: DeckTrack, wind: WindEpisode) -> Flight:
    """The drone in the state of an autopilot already holding position in the wind at rest (the
    simulator's ``World.trim``, with ``keep_view`` for the landing tasks)."""
    d, ctrl = flight.drone, flight.control
    dtype = d.position.dtype
    f = jnp.zeros(3, dtype)
    if p.wind is not None:
        f = wind_force(jnp.zeros(3, dtype), _air(p, wind, jnp.zeros((), dtype)), p.wind.drag)
    m = p.drone.mass
    g = p.drone.gravity
    thrust = jnp.stack([-f[0], -f[1], m * g - f[2]])
    norm = jnp.sqrt(jnp.sum(thrust * thrust))
    z = thrust / norm
    R = matrix_from_quaternion(d.quaternion)
    yaw = jnp.arctan2(R[1, 0], R[0, 0])
    xc = jnp.stack([jnp.cos(yaw), jnp.sin(yaw), jnp.zeros_like(yaw)])
    y = cross(z, xc)
    y = y / jnp.sqrt(jnp.sum(y * y))
    x = cross(y, z)
    R_new = jnp.stack([x, y, z], axis=1)
    shift = jnp.zeros(3, dtype)
    if p.keep_view:
        depth = d.position[2] - deck.position[2]
        cam = matvec(R_new, jnp.asarray(p.config.world.rig.camera_position, dtype))
        axis = -z
        depth_cam = depth + cam[2]
        hit = cam[:2] + axis[:2] * depth_cam / jnp.maximum(-axis[2], 1e-6)
        shift = jnp.concatenate([-hit, jnp.zeros(1, dtype)])
    w = jnp.sqrt(norm / 4.0 / p.drone.kf)
    z3 = jnp.zeros(3, dtype)
    drone = d._replace(
        position=d.position + shift,
        quaternion=quaternion_from_matrix(R_new),
        velocity=z3,
        angular_velocity=z3,
        rotor_speed=jnp.full(4, w, dtype),
    )
    a = f / m
    gains = p.gains
    ctrl = ctrl._replace(p_ref=ctrl.p_ref + shift * jnp.asarray([1.0, 1.0, 0.0], dtype))
    if gains.wind_hold and gains.dob_tau > 0.0:
        n = jnp.hypot(a[0], a[1])
        k = jnp.where(n > 0, jnp.minimum(1.0, gains.i_limit / jnp.where(n > 0, n, 1.0)), 1.0)
        ctrl = ctrl._replace(disturbance=a[:2] * k, v_prev=jnp.zeros(2, dtype), has_v_prev=jnp.asarray(True))
    elif gains.ki_pos > 0.0 and gains.wind_hold:
        i = -a[:2] / gains.ki_pos
        n = jnp.hypot(i[0], i[1])
        cap = gains.i_limit / gains.ki_pos
        k = jnp.where(n > 0, jnp.minimum(1.0, cap / jnp.where(n > 0, n, 1.0)), 1.0)
        ctrl = ctrl._replace(integral=ctrl.integral.at[:2].set(i * k))
    elif gains.ki_pos > 0.0:
        from ihrcf_env.fast.autopilot import CLASSIC_I_CLAMP

        i = jnp.clip(-a[:2] / gains.ki_pos, -CLASSIC_I_CLAMP, CLASSIC_I_CLAMP)
        ctrl = ctrl._replace(integral=ctrl.integral.at[:2].set(i))
    ctrl = ctrl._replace(
        thrust_model=m * jnp.sqrt(a[0] * a[0] + a[1] * a[1] + (g - a[2]) ** 2), a_model=-a[:2]
    )
    ok = (norm > 0.0) & jnp.isfinite(norm)
    out = flight._replace(drone=drone, control=ctrl)
    return jax.tree_util.tree_map(lambda new, old: jnp.where(ok, new, old), out, flight)


def _flight0(p: StepParams, ep: Episode, deck: DeckTrack, nav: NavState, wind: WindEpisode) -> Flight:
    dtype = p.dtype
    start = deck.position + jnp.stack([ep.offset[0], ep.offset[1], ep.altitude])
    drone = hover_state(p.drone, start, ep.yaw)
    ref = start
    if p.nav is not None:
        ref = nav_estimate(nav, start, drone.velocity, p.nav)[0]
    ctrl = controller_reset(p.drone, ref, ep.yaw)
    z3 = jnp.zeros(3, dtype)
    flight = Flight(
        drone, ctrl, jnp.asarray(False), jnp.asarray(False), z3, jnp.asarray([0.0, 0.0, 0.0, 1.0], dtype),
        jnp.asarray(0, jnp.int8), jnp.asarray(0), z3, z3,
    )  # fmt: skip
    if p.trimmed:
        flight = _trim(p, flight, deck, wind)
    return flight


def _no_touchdown(dtype: Any) -> tasks.TouchdownState:
    return tasks.TouchdownState(
        jnp.asarray(tasks.NO_CONTACT, jnp.int32),
        jnp.zeros((), dtype),
        jnp.zeros((), dtype),
        jnp.asarray(False),
    )


# -- reset -----------------------------------------------------------------------------------------
def reset_from_with(episode: Episode, draws: ReadDraws, params: StepParams) -> tuple[Any, EnvState]:
    """:func:`reset_from` with the first reading's noise given."""
    p = _check_params(params)
    if not isinstance(episode, Episode):
        raise TypeError(f"episode must be an Episode (ihrcf_env.fast.episode), got {type(episode).__name__}")
    ep = jax.tree_util.tree_map(
        lambda a: (
            jnp.asarray(a).astype(p.dtype)
            if jnp.issubdtype(jnp.asarray(a).dtype, jnp.floating)
            else jnp.asarray(a)
        ),
        episode,
    )
    dtype = p.dtype
    tick = jnp.asarray(0, jnp.int32)
    deck = _deck_first(p, ep, tick.astype(dtype))
    deck1 = _deck_next(p, ep, deck, jnp.asarray(1.0, dtype))
    q0 = quaternion_from_matrix(deck.rotation)
    wind = _wind_of(p, ep)
    nav = NavState(*(jnp.zeros(3, dtype) for _ in range(3)))
    if p.nav is not None:
        nav = nav_start(ep.nav0, p.nav)
    flight = _flight0(p, ep, deck, nav, wind)
    z3, z0 = jnp.zeros(3, dtype), jnp.zeros((), dtype)
    imu = ImuState(z3, z3, z3, z3, jnp.zeros(2, dtype), z0, z0)
    if p.imu is not None:
        imu = imu_reset(p.imu, ep.imu0)
    pipe = pipe_init(p.camera.pipe if p.camera is not None else 1, dtype)
    # the deck at reset moves towards its next pose (the simulator drives it before the first step;
    # its velocity then still holds the step's gravity compensation)
    q1 = quaternion_from_matrix(deck1.rotation)
    dpv = (deck1.body - deck.body) / p.dt + jnp.asarray([0.0, 0.0, p.drone.gravity * p.dt], dtype)
    dpv = dpv + cross(angular_velocity_between(q0, q1, p.dt), flight.drone.position - deck.body)
    st = EnvState(
        flight, deck, q0, deck.body, q0, tick, jnp.asarray(0, jnp.int32), ep, wind, nav, imu,
        jnp.asarray(0, jnp.int32), jnp.zeros(4, dtype), jnp.zeros(4, bool), pipe, jnp.asarray(0, jnp.int32),
        jnp.asarray(False), jnp.asarray(False), jnp.zeros((), dtype), jnp.asarray(False),
    )  # fmt: skip
    d = flight.drone
    tof = tof_reading(
        p, ep, d.position, matrix_from_quaternion(d.quaternion), deck.position, deck.rotation,
        jnp.zeros((), dtype), draws.tof_z[0], draws.tof_u[0],
    )  # fmt: skip
    if p.tof.ticks_per_sample is not None:
        st = st._replace(tof_next=_clock_index(p, tick) + 1, tof_ranges=tof[0], tof_valid=tof[1])
    st, raw = _read_end(p, st, draws, jnp.zeros(3, dtype), tof)
    s = _task_state(flight, deck, dpv)
    phi = jnp.zeros((), dtype)
    goal = p.config.task.landing
    if goal is not None:
        phi = tasks.landing_potential(s, goal.reward)
    st = st._replace(phi=phi)
    truth = _truth(p, s, flight, q0, _air(p, wind, jnp.zeros((), dtype)))
    return p.observe(raw, truth), _strong(st)


def reset_from(episode: Episode, key: Any, params: StepParams) -> tuple[Any, EnvState]:
    """(observation, state) of the episode ``episode``; the first reading's noise from ``key``."""
    p = _check_params(params)
    return reset_from_with(episode, draw_reads(_check_key(key), p), p)


def reset(key: Any, params: StepParams) -> tuple[Any, EnvState]:
    """(observation, state) of a new episode drawn from ``key``."""
    p = _check_params(params)
    k = jax.random.split(_check_key(key))
    return reset_from_with(draw_episode(k[0], p), draw_reads(k[1], p), p)


# -- draws -----------------------------------------------------------------------------------------
def draw_reads(key: Array, params: StepParams) -> ReadDraws:
    """One reading's noise drawn from ``key``."""
    p, dt = params, params.dtype
    k = jax.random.split(key, 6)
    m = p.tof.samples
    return ReadDraws(
        jax.random.normal(k[0], (m, 4), dt),
        jax.random.uniform(k[1], (m, 4), dt),
        jax.random.normal(k[2], (READ_DRAWS,), dt),
        jax.random.normal(k[3], (4, 2), dt),
        jax.random.uniform(k[4], (), dt),
        jax.random.uniform(k[5], (), dt),
    )


def draw_step(key: Array, params: StepParams) -> StepDraws:
    """One control step's noise drawn from ``key``."""
    k = jax.random.split(key)
    nav = jax.random.normal(k[0], (params.substeps, 6), params.dtype)
    return StepDraws(nav, draw_reads(k[1], params))


# -- step ------------------------------------------------------------------------------------------
def step_with(
    draws: StepDraws, state: EnvState, action: Any, params: StepParams
) -> tuple[Any, EnvState, Array, Array, StepInfo]:
    """One control step with its noise given: (obs, state, reward, done, info)."""
    p = _check_params(params)
    st = _check_state(state, p)
    a, finite = _check_action(action, p)
    dtype, S, dt = p.dtype, p.substeps, p.dt
    ep = st.episode
    setpoint = a * jnp.asarray(p.max_velocity, dtype)
    tick0 = st.tick

    # the deck's poses at ticks tick0 .. tick0 + S
    if p.deck.kind == "ship":
        # the ship's components as phasors rotated tick by tick (two transcendentals per component
        # and step instead of per tick)
        assert p.deck.ship is not None
        ship = p.deck.ship
        phasor = ship_phasor((tick0 + 1).astype(dtype) * dt + ep.deck_time, dt, ep.deck, ship)

        def ship_body(carry: tuple[DeckTrack, ShipPhasor], _: Array) -> tuple[tuple, DeckTrack]:
            prev, ph = carry
            nxt = _deck_at(p, prev, *ship_pose_of_phasor(ph, ep.deck, ship))
            return (nxt, ship_phasor_advance(ph)), nxt

        _, decks = lax.scan(ship_body, (st.deck, phasor), None, length=S)
    else:

        def deck_body(prev: DeckTrack, j: Array) -> tuple[DeckTrack, DeckTrack]:
            nxt = _deck_next(p, ep, prev, (tick0 + j).astype(dtype))
            return nxt, nxt

        _, decks = lax.scan(deck_body, st.deck, jnp.arange(1, S + 1))
    deck_all = jax.tree_util.tree_map(lambda a0, a1: jnp.concatenate([a0[None], a1]), st.deck, decks)
    quats = jnp.concatenate([st.deck_quat[None], jax.vmap(quaternion_from_matrix)(decks.rotation)])
    times = (tick0 + jnp.arange(S)).astype(dtype) * dt
    air = jax.vmap(lambda t: _air(p, st.wind, t))(times)
    one = p.advance

    def tick_body(carry: tuple, j: Array) -> tuple[tuple, tuple[Array, Array, Array, Array]]:
        f, nav, nxt, rng_m, ranges, valid, td, tof_t = carry
        code0 = f.code
        top = lax.dynamic_slice_in_dim(deck_all.position, j, 2)
        qs = lax.dynamic_slice_in_dim(quats, j, 2)
        nav_arg = None
        if p.nav is not None:
            nav_arg = (NavState(nav.ep[None], nav.ev[None], nav.white[None]), p.nav)
        f2 = advance(one, f, setpoint, top, qs, air[j][None] if p.wind is not None else None, nav_arg)
        if p.nav is not None:
            nav = nav_step(nav, draws.nav[j], p.nav)
        tick = tick0 + j + 1
        deck_j = jax.tree_util.tree_map(lambda x: x[j + 1], deck_all)
        # the touchdown record of the first contact
        touched = (code0 == 0) & (f2.code != 0)
        dpv, _ = _point_velocity(deck_j.body, qs[0], qs[1], deck_all.body[j], dt, f2.drone.position)
        s = _task_state(f2, deck_j, dpv)
        new_td = tasks.touchdown_state(s, f2.code.astype(jnp.int32), f2.touch_velocity, p.deck.top_half)
        td = jax.tree_util.tree_map(lambda n, o: jnp.where(touched, n, o), new_td, td)
        f2 = f2._replace(tick=jnp.where(code0 != 0, f.tick, jnp.where(touched, j + 1, 0)))
        # the ToF's sample clock (the sample itself is read after the ticks, at the last one due)
        due = jnp.asarray(False)
        if p.tof.ticks_per_sample is not None:
            due = _clock_index(p, tick) >= nxt
            nxt = jnp.where(due, _clock_index(p, tick) + 1, nxt)
            rng_m = rng_m + due.astype(jnp.int32)
        d = f2.drone
        return (f2, nav, nxt, rng_m, ranges, valid, td, tof_t), (due, rng_m, d.position, d.quaternion)

    f_in = st.flight._replace(code=jnp.where(st.flight.latched, st.flight.code, 0).astype(jnp.int8))
    init = (
        f_in,
        st.nav,
        st.tof_next,
        jnp.asarray(0, jnp.int32),
        st.tof_ranges,
        st.tof_valid,
        _no_touchdown(dtype),
        jnp.zeros((), dtype),
    )
    (flight, nav, nxt, _, ranges, valid, td, _), ticks = lax.scan(tick_body, init, jnp.arange(S))
    if p.tof.ticks_per_sample is not None:
        # the ToF sample of the period's last due tick (the earlier ones are overwritten by it)
        dues, counts, positions, quaternions = ticks
        last = S - 1 - jnp.argmax(dues[::-1])
        m = jnp.clip(counts[last] - 1, 0, p.tof.samples - 1)
        r, v = tof_reading(
            p, ep, positions[last], matrix_from_quaternion(quaternions[last]), deck_all.position[last + 1],
            deck_all.rotation[last + 1], (tick0 + last + 1).astype(dtype) * dt, draws.read.tof_z[m],
            draws.read.tof_u[m],
        )  # fmt: skip
        ranges = jnp.where(jnp.any(dues), r, ranges)
        valid = jnp.where(jnp.any(dues), v, valid)
    # a contact latched in an earlier step is not this step's touchdown
    td = jax.tree_util.tree_map(lambda n, t: jnp.where(st.flight.latched, n, t), _no_touchdown(dtype), td)
    deck = jax.tree_util.tree_map(lambda x: x[S], deck_all)
    tick = tick0 + S
    st2 = st._replace(
        flight=flight, deck=deck, deck_quat=quats[S], deck_prev_body=deck_all.body[S - 1],
        deck_prev_quat=quats[S - 1], tick=tick, steps=st.steps + 1, nav=nav, tof_next=nxt,
        tof_ranges=ranges, tof_valid=valid,
    )  # fmt: skip
    d = flight.drone
    if p.tof.ticks_per_sample is None:
        tof = tof_reading(
            p, ep, d.position, matrix_from_quaternion(d.quaternion), deck.position, deck.rotation,
            tick.astype(dtype) * dt, draws.read.tof_z[0], draws.read.tof_u[0],
        )  # fmt: skip
    else:
        tof = (ranges, valid)
    st2, raw = _read_end(p, st2, draws.read, flight.acceleration, tof)
    dpv, _ = _point_velocity(deck.body, quats[S - 1], quats[S], deck_all.body[S - 1], dt, d.position)
    s = _task_state(flight, deck, dpv)
    task = p.config.task
    goal = task.landing
    offset = tasks.tag_offset(s)
    radius = goal.success_radius if goal is not None else None
    code = tasks.classify(s, td, task.thresholds, task.arena, radius, offset)
    code = jnp.where(finite, code, INVALID_ACTION)
    terms: Any
    if goal is not None:
        terms, phi = tasks.landing_reward(
            s, a, code, td, st.phi, goal.reward, task.thresholds, goal.success_radius, p.control_dt, offset
        )
    else:
        terms, phi = tasks.hover_reward(s, a, code, task.reward, offset), st.phi
    reward = tasks.total(tuple(terms))
    done = tasks.is_terminal(code)
    st2 = st2._replace(phi=jnp.asarray(phi, dtype), done=done)
    truth = _truth(p, s, flight, quats[S], _air(p, st.wind, tick.astype(dtype) * dt))
    info = StepInfo(raw, truth, code, terms, td, tick.astype(dtype) * dt)
    return p.observe(raw, truth), _strong(st2), jnp.asarray(reward, dtype), done, info


def step_env(
    key: Any, state: EnvState, action: Any, params: StepParams
) -> tuple[Any, EnvState, Array, Array, StepInfo]:
    """One control step, its noise drawn from ``key`` (no reset at the episode's end)."""
    p = _check_params(params)
    return step_with(draw_step(_check_key(key), p), state, action, p)


def step(
    key: Any, state: EnvState, action: Any, params: StepParams
) -> tuple[Any, EnvState, Array, Array, StepInfo]:
    """One control step, its noise drawn from ``key``; when the episode ends, the state and
    observation returned are those of a new episode drawn from ``key`` (gymnax's convention)."""
    p = _check_params(params)
    k = jax.random.split(_check_key(key))
    obs, st, reward, done, info = step_with(draw_step(k[0], p), state, action, p)
    obs_r, st_r = reset(k[1], p)
    st = jax.tree_util.tree_map(lambda r, s: jnp.where(done, r, s), st_r, st)
    obs = jax.tree_util.tree_map(lambda r, o: jnp.where(done, r, o), obs_r, obs)
    return obs, st, reward, done, info
