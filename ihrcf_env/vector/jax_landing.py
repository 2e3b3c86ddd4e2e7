"""The landing task as one functional env for the JAX backend: the physics/sensor step and the
observation joined, with its Gymnasium spaces.

:class:`LandingFunctional` joins :mod:`ihrcf_env.fast.step` (physics, sensors, task rules; its
observation hook returns the raw reading and the truth) and :mod:`ihrcf_env.fast.observe` (the
estimators and the normalised observation, in the layout of the PyBullet env's
``LandingObservation``) into the functions a trainer or :class:`~ihrcf_env.vector.jax_env.JaxVectorEnv`
steps, one env per call: ``draw``, ``draw_host``, ``reset_from`` (``reset_from_info`` with the
reset's info), ``reset``, ``step``. Its state is ``(EnvState, ObserveState)``; its ``info`` holds
arrays: the episode time, the camera's sample time and tag status, the truth (the PyBullet env's
``info`` keys, :data:`TRUTH_KEYS`), each estimate's :class:`~ihrcf_env.fast.observe.EstimateInfo`
(``info["estimates"]``), and after a step the reward terms, the outcome code (``outcome_code``;
:data:`ihrcf_env.fast.step.INVALID_ACTION` for a non-finite action), the step's touchdown record
and, with ``deck_forecast``, the forecast (``info["forecast"]``: ``horizons`` (H,) s, ``mean`` and
``std`` (H, 4) in the observation block's frames and units, ``quiet_probability``, ``valid``,
``samples``, as the PyBullet env's). :meth:`LandingFunctional.host_info` turns these arrays into
the PyBullet env's ``info`` (strings for the outcome and the reasons, float64 values).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.core.landing_layout import FORECAST
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.fast import observe as ob
from ihrcf_env.fast import step as st
from ihrcf_env.fast.contact import BASE, DECK, GROUND
from ihrcf_env.fast.deck_motion import leg_lengths
from ihrcf_env.fast.detector import STATUS_NAMES
from ihrcf_env.fast.episode import draw_episode, host_episode, start_towards_deck
from ihrcf_env.fast.linalg3 import euler_from_matrix
from ihrcf_env.fast.params import make_params
from ihrcf_env.fast.step import INVALID_ACTION, check_tree, state_spec
from ihrcf_env.tasks import CONTACT_NAMES, TaskState, TouchdownState, describe
from ihrcf_env.tasks import SUCCESS as _SUCCESS

__all__ = ["CURRICULUM_ALTITUDE", "LM_ITERATIONS", "TRUTH_KEYS", "LandingFunctional"]

#: The lowest start of a start curriculum (m above the deck origin;
#: :meth:`LandingFunctional.reset_stage`).
CURRICULUM_ALTITUDE = 0.6

#: The truth in the ``info`` of a reset and a step, as the PyBullet env gives it (world and body
#: frames, m, rad, m/s; quaternions x, y, z, w).
TRUTH_KEYS = (
    "deck_position_body",
    "deck_euler_body",
    "deck_rotation_body",
    "drone_position_world",
    "drone_quaternion_world",
    "deck_position_world",
    "deck_quaternion_world",
    "leg_lengths",
    "contact_deck",
    "contact_ground",
    "wind_velocity",
    "relative_velocity",
    "tag_offset",
)
#: The reason of a tag reading before the first camera frame (the PyBullet env's).
NO_FRAME_YET = "no camera frame yet"
#: ``info["crash_reason"]`` of :data:`~ihrcf_env.fast.step.INVALID_ACTION`.
INVALID_ACTION_REASON = "non-finite action (NaN or inf): the zero command was flown"

#: The LM steps that polish each of ATDA's IPPE poses on the JAX backend (cv2 stops after at most
#: 20 by its own rules; a fixed count runs every step for every env, so it is kept small: the
#: difference to the 20-step pose is bounded in tests/fast/test_pnp.py).
LM_ITERATIONS = 5


def _raw_and_truth(raw: Any, truth: Any) -> Any:
    return raw, truth


class LandingFunctional:
    """The landing task of a resolved ``config`` as pure functions of one env (module
    docstring); ``dtype`` the float type (float64 needs x64 while tracing and running);
    ``max_steps`` the episode's step limit; ``lm_iterations`` the LM steps polishing each IPPE pose
    (:data:`LM_ITERATIONS`; 20 gives cv2's poses)."""

    def __init__(
        self,
        config: DeckLandingConfig,
        dtype: Any = jnp.float64,
        max_steps: int = 600,
        lm_iterations: int = LM_ITERATIONS,
    ) -> None:
        self.config = config
        self.step_params = make_params(config, observe=_raw_and_truth, dtype=dtype, max_steps=max_steps)
        self.observe_params = ob.observe_params(config, lm_iterations)
        op = self.observe_params
        self.obs_slices = dict(op.slices)
        self.obs_scales = dict(op.scales)
        self.observation_space = spaces.Box(
            np.asarray(op.low, np.float32), np.asarray(op.high, np.float32), dtype=np.float32
        )
        self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
        self.params: Any = ()
        self._obs_state_specs: dict[bool, Any] = {}

    def draw_host(self, rng: np.random.Generator) -> tuple[int, Any]:
        """The episode key and episode the PyBullet env draws next from its generator ``rng``."""
        streams = SeedStreams.from_generator(rng)
        return streams.key, host_episode(self.step_params, streams)

    def draw(self, key: Any, params: Any) -> Any:
        return draw_episode(key, self.step_params)

    def reset_from_info(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any, dict[str, Any]]:
        """(observation, state, info) of the episode ``episode`` (info: the module docstring's
        arrays without the step's)."""
        (raw, truth), env_state = st.reset_from(episode, key, self.step_params)
        op = self.observe_params
        obs, obs_state, estimates = ob.observe(op, ob.observe_init(op), raw, truth)
        info = self._info(raw, truth, env_state, estimates)
        info["is_success"] = jnp.asarray(False)
        return obs, (env_state, obs_state), info

    def reset_from(self, episode: Any, key: Any, params: Any) -> tuple[Any, Any]:
        obs, state, _ = self.reset_from_info(episode, key, params)
        return obs, state

    def reset(self, key: Any, params: Any) -> tuple[Any, Any]:
        k1, k2 = jax.random.split(key)
        return self.reset_from(self.draw(k1, params), k2, params)

    def step(self, key: Any, state: Any, action: Any, params: Any) -> tuple[Any, Any, Any, Any, Any]:
        env_state, obs_state = self._check_state(state)
        (raw, truth), env_state, reward, done, info = st.step_env(key, env_state, action, self.step_params)
        obs, obs_state, estimates = ob.observe(self.observe_params, obs_state, raw, truth)
        out = self._info(raw, truth, env_state, estimates)
        out["is_success"] = info.outcome == jnp.asarray(_SUCCESS)
        out["outcome_code"] = info.outcome
        for name, value in zip(type(info.terms).__annotations__, info.terms, strict=True):
            out[f"reward_{name}"] = value
        p = self.step_params
        td = info.touchdown
        touch_tick = env_state.tick - p.substeps + env_state.flight.tick.astype(env_state.tick.dtype)
        out["touchdown"] = {
            "contact": td.contact,
            "time": touch_tick.astype(p.dtype) * p.dt,
            "relative_vertical_speed": td.relative_vertical_speed,
            "relative_tilt": td.relative_tilt,
            "on_deck": td.on_deck,
        }
        fc, feed, fp = obs_state.forecast, obs_state.feed, self.observe_params.forecast
        if fc is not None and feed is not None and fp is not None:
            out[FORECAST] = {
                "horizons": jnp.asarray(fp.forecast.horizons, fc.mean.dtype),
                "mean": fc.mean,
                "std": fc.std,
                "quiet_probability": fc.quiet,
                "valid": fc.valid,
                "samples": feed.samples,
            }
        return obs, (env_state, obs_state), reward, done, out

    # -- the staged form: the estimator stage once per env and step -------------------------------
    def step_stage(self, key: Any, state: Any, action: Any, params: Any) -> tuple[Any, Any, Any, Any, Any]:
        """:meth:`step` without the estimator stage: ``(reading, state, reward, terminated, info)``,
        ``reading`` the step's ``(RawReading, Truth)`` for :meth:`finish`; ``info`` holds
        ``outcome`` and ``is_success``."""
        env_state, obs_state = state
        reading, env_state, reward, done, info = st.step_env(key, env_state, action, self.step_params)
        out = {"outcome": info.outcome, "is_success": info.outcome == jnp.asarray(_SUCCESS)}
        return reading, (env_state, obs_state), reward, done, out

    def reset_stage(self, key: Any, params: Any, start_scale: Any = None) -> tuple[Any, Any]:
        """:meth:`reset` without the estimator stage: ``(reading, state)``, the stage's state that
        of an episode's start (:meth:`finish` makes the first observation). ``start_scale`` in
        [0, 1] (a trainer's start curriculum; None: the task's own start) brings the drawn start
        towards the deck: the altitude above the deck origin to :data:`CURRICULUM_ALTITUDE` plus
        the scale times the rest, the horizontal offset times the scale."""
        k1, k2 = jax.random.split(key)
        episode = self.draw(k1, params)
        if start_scale is not None:
            episode = start_towards_deck(episode, start_scale, CURRICULUM_ALTITUDE)
        reading, env_state = st.reset_from(episode, k2, self.step_params)
        return reading, (env_state, ob.observe_init(self.observe_params))

    def finish(self, reading: Any, state: Any) -> tuple[Any, Any]:
        """The observation of ``reading`` (:meth:`step_stage` or :meth:`reset_stage`) and the state
        with the estimator stage advanced: ``reset_stage`` then ``finish`` is :meth:`reset`,
        ``step_stage`` then ``finish`` is :meth:`step`."""
        env_state, obs_state = state
        raw, truth = reading
        obs, obs_state, _ = ob.observe(self.observe_params, obs_state, raw, truth)
        return obs, (env_state, obs_state)

    def privileged(self, reading: Any) -> Any:
        """The ground truth of a reading as a critic's privileged inputs (20,): the drone's
        position relative to the deck origin (world, m), the deck origin in the body frame (m), the
        velocity relative to the deck point under the drone (world, m/s), the drone's and the deck's
        quaternions (x, y, z, w) and the wind (world, m/s)."""
        _, truth = reading
        return jnp.concatenate(
            [
                truth.drone_position_world - truth.deck_position_world,
                truth.deck_position_body,
                truth.relative_velocity,
                truth.drone_quaternion_world,
                truth.deck_quaternion_world,
                truth.wind_velocity,
            ]
        )

    # -- the info ---------------------------------------------------------------------------
    def _info(self, raw: Any, truth: Any, env_state: Any, estimates: dict[str, Any]) -> dict[str, Any]:
        """The arrays of a reset's and a step's info (module docstring)."""
        p = self.step_params
        out: dict[str, Any] = {"time": raw.time}
        if p.camera is not None:
            seen = raw.camera_frame > 0
            nan = jnp.full((), jnp.nan, raw.time.dtype)
            out["camera_time"] = jnp.where(seen, raw.time - raw.camera_age, nan)
            out["camera_age"] = jnp.where(seen, raw.camera_age, nan)
            out["tag_status"] = jnp.where(seen, raw.tag_status, ob.NO_FRAME_STATUS)
        deck = env_state.deck
        code = env_state.flight.code
        d = truth.drone_position_world - truth.deck_position_world
        out.update(
            deck_position_body=truth.deck_position_body,
            deck_euler_body=euler_from_matrix(truth.deck_rotation_body),
            deck_rotation_body=truth.deck_rotation_body,
            drone_position_world=truth.drone_position_world,
            drone_quaternion_world=truth.drone_quaternion_world,
            deck_position_world=truth.deck_position_world,
            deck_quaternion_world=truth.deck_quaternion_world,
            leg_lengths=leg_lengths(
                deck.position, deck.rotation, jnp.asarray(p.deck.top_joints), jnp.asarray(p.deck.base_joints)
            ),
            contact_deck=code == DECK,
            contact_ground=(code == GROUND) | (code == BASE),
            wind_velocity=truth.wind_velocity,
            relative_velocity=truth.relative_velocity,
            tag_offset=jnp.sqrt(d[0] * d[0] + d[1] * d[1]),
        )
        out["estimates"] = dict(estimates)
        return out

    def host_info(self, info: dict[str, Any]) -> dict[str, Any]:
        """The PyBullet env's ``info`` columns of rows of :meth:`step`'s or :meth:`reset_from_info`'s
        ``info`` (numpy arrays with a leading row axis): strings for ``tag_reason``, ``outcome``,
        ``crash_reason`` and the estimates' reasons (object arrays), float64 for the floats, the
        touchdown as a nested dict whose ``_touchdown`` marks the rows that touched down."""
        out: dict[str, Any] = {}
        n = len(info["time"])
        for key, value in info.items():
            if key == "tag_status":
                out["tag_reason"] = _texts(value, _tag_reason)
            elif key == "estimates":
                for name, e in value.items():
                    out[f"{name}_reason"] = self._reasons(name, e, n)
                    out[f"{name}_residual"] = np.asarray(e.residual, np.float64)
                    out[f"{name}_age"] = np.asarray(e.age, np.float64)
            elif key == "outcome_code":
                out["outcome"] = _texts(value, _outcome_text)
                out["crash_reason"] = self._crash_reasons(info)
            elif key == "touchdown":
                touched = np.asarray(value["contact"]) != 0
                if touched.any():
                    out["touchdown"] = {
                        "body": _texts(value["contact"], lambda c: CONTACT_NAMES[c]),
                        **{k: _float64(v) for k, v in value.items() if k not in ("contact",)},
                    }
                    out["_touchdown"] = touched
            elif isinstance(value, dict):
                out[key] = {k: _float64(v) for k, v in value.items()}
            else:
                out[key] = _float64(value)
        return out

    def _reasons(self, name: str, e: Any, n: int) -> NDArray[np.object_]:
        """The reason texts of estimator ``name`` over ``n`` rows ('' where valid)."""
        texts = np.full(n, "", dtype=object)
        for i in np.flatnonzero(~np.asarray(e.valid, bool)):
            texts[i] = ob.reason_text(self.observe_params, name, type(e)(*(np.asarray(f)[i] for f in e)))
        return texts

    def _crash_reasons(self, info: dict[str, Any]) -> NDArray[np.object_]:
        """``crash_reason`` of each row ('' unless a crash: :func:`ihrcf_env.tasks.describe`)."""
        codes = np.asarray(info["outcome_code"])
        texts = np.full(len(codes), "", dtype=object)
        task, td = self.config.task, info["touchdown"]
        radius = task.landing.success_radius if task.landing is not None else None
        for i in np.flatnonzero(codes > _SUCCESS):
            if codes[i] == INVALID_ACTION:
                texts[i] = INVALID_ACTION_REASON
                continue
            fields = ("contact", "relative_vertical_speed", "relative_tilt", "on_deck")
            touch = TouchdownState(*(np.asarray(td[k])[i] for k in fields))
            state = TaskState(
                np.asarray(info["drone_position_world"][i], np.float64), None, None,
                np.asarray(info["deck_position_world"][i], np.float64), None, None,
            )  # fmt: skip
            texts[i] = describe(int(codes[i]), touch, state, task.thresholds, radius)
        return texts

    def _check_state(self, state: Any) -> tuple[Any, Any]:
        """``state`` checked to be this env's ``(EnvState, ObserveState)`` (structure, shapes and
        dtypes, at trace time), TypeError / ValueError naming ``state`` otherwise."""
        if not isinstance(state, tuple) or len(state) != 2:
            raise TypeError(f"state must be (EnvState, ObserveState) from reset, got {type(state).__name__}")
        env_state, obs_state = state
        if not isinstance(env_state, st.EnvState) or not isinstance(obs_state, ob.ObserveState):
            raise TypeError(
                "state must be the (EnvState, ObserveState) pair of reset, got "
                f"({type(env_state).__name__}, {type(obs_state).__name__})"
            )
        x64 = jax.dtypes.canonicalize_dtype(np.float64) == np.float64
        if x64 not in self._obs_state_specs:
            op = self.observe_params
            self._obs_state_specs[x64] = jax.eval_shape(lambda: ob.observe_init(op))
        forecast = "" if self.observe_params.forecast is None else " with deck_forecast"
        check_tree("state[0]", env_state, state_spec(self.step_params), f" (this env's{forecast})")
        check_tree("state[1]", obs_state, self._obs_state_specs[x64], f" (this env's{forecast})")
        return env_state, obs_state


def _float64(value: Any) -> NDArray[Any]:
    """``value`` as a numpy array, floats as float64 (the PyBullet env's info)."""
    a = np.asarray(value)
    return a.astype(np.float64) if a.dtype.kind == "f" else a


def _texts(codes: Any, text: Any) -> NDArray[np.object_]:
    """An object array of ``text(code)`` per row (each distinct code looked up once)."""
    c = np.asarray(codes).astype(np.int64)
    out = np.empty(len(c), dtype=object)
    for code in np.unique(c):
        t = text(int(code))
        for i in np.flatnonzero(c == code):
            out[i] = t
    return out


def _tag_reason(status: int) -> str:
    if status == ob.NO_FRAME_STATUS:
        return NO_FRAME_YET
    return STATUS_NAMES[status] if 0 <= status < len(STATUS_NAMES) else "tag not detected"


def _outcome_text(code: int) -> str:
    """The PyBullet env's ``info["outcome"]`` of an outcome code."""
    return "flying" if code == 0 else ("success" if code == _SUCCESS else "crash")
