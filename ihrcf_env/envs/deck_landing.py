"""``DeckLandingEnv``: land a quadrotor on a moving Stewart-platform deck.

Observation (``gymnasium.spaces.Dict``):

================  =======================  =====================================================
key               shape / dtype            meaning
================  =======================  =====================================================
``image``         (H, W, 3) uint8          downward camera, TinyRenderer (``camera_output="image"``,
                                           the default of the rendered camera; absent if camera=False)
``tag_corners``   (4, 2) float32, px       ``camera_output="corners"`` instead of ``image``: the tag's
                                           corners (OpenCV pixel centres and corner order), zeros
                                           when not detected (``info["tag_reason"]`` says why)
``tag_detected``  Discrete(2)              ``camera_output="corners"``: 1 = the tag was detected
``tag_status``    Discrete(len(TAG_STATUS))  ``camera_output="corners"``: why not (0: detected; the
                                           reasons in :data:`~ihrcf_env.sim.sensors.base.TAG_STATUS`)
``camera_age``    (1,) float32, s          age of the camera frame shown, since its exposure (0
                                           when new without ``CameraConfig.latency``; 10 before
                                           the first frame arrives)
``camera_frame``  (1,) int64               with a camera latency only: frames delivered so far
``tof_age``       (1,) float32, s          with ``ToFConfig.rate_hz`` only: age of the ranges
``imu_age``       (1,) float32, s          with ``IMUConfig.rate_hz`` only: age of the IMU sample
``ranges``        (4,) float32, m          ToF ps1..ps4 along the optical axis, in [0, max_range]
``ranges_valid``  (4,) int8                1 = valid reading; invalid readings read max_range
``imu``           Dict                     ``quaternion`` (4,) x, y, z, w world-from-body;
                                           ``angular_velocity`` (3,) rad/s body frame;
                                           ``linear_acceleration`` (3,) m/s^2 specific force, body
``nav_velocity``  (3,) float32, m/s        the autopilot's velocity estimate (world frame): the
                                           truth or the GNSS/INS estimate (``autopilot_feedback``)
================  =======================  =====================================================

Camera (``camera_model``): ``"rendered"`` (default) renders with TinyRenderer; with
``camera_output="corners"`` it renders only the window around the tag's projection and detects the
tag there (the full frame's corners, see ``docs/camera-models.md``). ``"projected"`` renders nothing: the tag
corners are projected through the true camera and a detector model fitted on rendered frames
(``ihrcf-fit-detector``) adds the detector's noise and failures. ``camera_hz``
(default: the control rate, must divide it) delivers a frame every ``control_hz / camera_hz`` steps;
in between the last frame is repeated and ``camera_age`` (s) says how old it is.

Action: ``Box(-1, 1, (4,))``, values outside are clipped (NaN/inf raise ValueError).
``"velocity"`` mode: ``(vx, vy, vz, yaw_rate) = action * max_velocity`` with vx, vy in the heading
frame (x forward along the drone's yaw, y left), vz world up, yaw rate about world z; tracked by
the built-in cascaded controller, which holds position at zero command. ``"motors"`` mode: motor
i's thrust is ``(action[i] + 1) / 2`` of its maximum (front-left, front-right, rear-right,
rear-left).

Reward per step (each term also in ``info`` as ``reward_<name>``): ``position = -|e_xy| - 0.2 e_z``
(e = drone minus deck origin, world, m), ``velocity = -0.1 |v_rel|``, ``attitude = -0.1 tilt``
(rad), ``action = -0.01 |a|^2``, and ``terminal = +100`` on a successful touchdown, ``-100`` on a
crash. Termination: touchdown (success if the relative vertical speed < 0.5 m/s, the relative tilt
< 10 deg and the drone is over the deck; a crash otherwise), a tilt > 60 deg, or leaving the arena.
Truncation only by ``max_episode_steps`` (TimeLimit). The weights and thresholds are the defaults of
:class:`~ihrcf_env.config.task.RewardWeights` and
:class:`~ihrcf_env.config.task.Thresholds`; the rules are the pure functions of
:mod:`ihrcf_env.tasks` (:func:`~ihrcf_env.tasks.classify`, :func:`~ihrcf_env.tasks.hover_reward`).

Misuse raises: a bad option TypeError/ValueError naming it (before any PyBullet client exists),
``step`` after a terminated episode or after ``close`` RuntimeError, copying or pickling TypeError.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, NoReturn, SupportsIndex

import gymnasium as gym
import numpy as np
import pybullet as p
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env import tasks
from ihrcf_env.config.landing import DeckLandingConfig
from ihrcf_env.config.make import make_config
from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.arrays import clip
from ihrcf_env.core.checks import check_mapping
from ihrcf_env.core.frames import euler_from_matrix, matrix_from_quat, quat_from_matrix
from ihrcf_env.core.profiles import MotionProfile
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.envs.render import EnvRenderer
from ihrcf_env.envs.vector_options import refuse_vector_options
from ihrcf_env.sim.disturbances import Wind
from ihrcf_env.sim.registry import SENSORS
from ihrcf_env.sim.sensing import CAMERA_SENSORS, Snapshot
from ihrcf_env.sim.sensors.base import TAG_STATUS
from ihrcf_env.sim.world import Touchdown, World, touchdown_arrays
from ihrcf_env.tasks import episode

RESET_OPTIONS = episode.RESET_OPTIONS
#: Deck profiles drawn at random per episode (a draw the legs cannot follow is drawn again).
RANDOM_PROFILES = episode.RANDOM_PROFILES
#: Draws of a random sea per reset before giving up.
MAX_DECK_DRAWS = episode.MAX_DECK_DRAWS
#: Upper bound (s) of ``camera_age`` in the observation.
MAX_SENSOR_AGE = 10.0
#: Bound (m/s) of ``nav_velocity`` in the observation.
MAX_NAV_VELOCITY = 20.0

_NO_COPY = (
    "a DeckLandingEnv owns a live PyBullet physics client, which cannot be copied or pickled; make "
    "another env with gym.make(...) and the same kwargs instead (vector envs: pass a function that "
    "makes the env, as gym.vector.AsyncVectorEnv expects)"
)


class DeckLandingEnv(gym.Env):
    """Quadrotor on a 6-DOF Stewart deck, sensed by a downward camera and four ToF beams: the raw
    env of the hover task (``ihrcf_env/DeckHoverRaw-v0``) and the base of the landing tasks.

    Frames and conventions: see :mod:`ihrcf_env.core.frames`. Ground truth is in ``info``: the deck
    pose in the drone body frame (``deck_position_body`` m, ``deck_euler_body`` roll/pitch/yaw rad),
    world poses of drone and deck, the six leg lengths and contact flags.

    The env's one input is a validated :class:`~ihrcf_env.config.landing.DeckLandingConfig`
    (``config``; or keyword options, validated by :func:`~ihrcf_env.config.make.make_config` before
    any PyBullet client exists). ``self.config`` is that config. Randomness: ``reset(seed=s)``
    seeds ``np_random``; each episode then draws one key from it and spawns independent streams
    (:class:`~ihrcf_env.core.seeding.SeedStreams`) for the start (``"start"``), the deck motion
    (``"deck"``), the wind (``"wind"``), each disturbance and each sensor, so the camera model, a
    sensor preset or the estimator set never change the start, deck or wind of a seed. The env
    cannot be copied or pickled (it owns a physics client); a closed env raises RuntimeError on use;
    an env dropped without ``close()`` releases its client when garbage-collected. Only one
    ``render_mode="human"`` env can be open per process (one PyBullet GUI).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}
    #: The task whose defaults ``**options`` take (see :data:`~ihrcf_env.config.make.TASK_DEFAULTS`).
    task_name = "hover"

    def __init__(self, config: DeckLandingConfig | None = None, **options: Any) -> None:
        self._closed = True  # until the world exists
        if config is None:
            refuse_vector_options(options)
            config = make_config(task=self.task_name, **{"raw": True, **options})
        elif options:
            raise TypeError(f"give either config or options, not both (got config and {sorted(options)})")
        elif not isinstance(config, DeckLandingConfig):
            raise TypeError(f"config must be a DeckLandingConfig (ihrcf_env.make_config), got {config!r}")
        cfg = config
        gui = cfg.render_mode == "human"
        #: the chase view and GUI camera (claims the process's one GUI first with "human")
        self.renderer = EnvRenderer(cfg.render_mode, cfg.chase_size)
        self.config: DeckLandingConfig = cfg
        self.render_mode = cfg.render_mode
        self.metadata = {**self.metadata, "render_fps": cfg.world.control_hz}
        self.observation_space = _observation_space(cfg.world)
        self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)
        self._profile: MotionProfile | None = None  # None: no episode yet (reset() first)
        self._episode_over = False
        self._last_touchdown: Touchdown | None = None
        self._tag_reason = ""
        cam = cfg.world.camera
        self._corner_bound = float(max(cam.width, cam.height)) if cam is not None else 0.0
        self._max_range = float(cfg.world.tof.max_range)
        self._camera_name = ""  # the camera sensor's name in the world, once it exists
        #: the env's wind (None: calm air); its force is one of the world's disturbances
        self.wind: Wind | None = Wind(cfg.wind) if cfg.wind is not None else None

        try:
            self.world = World(cfg.world, gui=gui)  # releases its client itself if it fails
        except BaseException:
            self.renderer.release()
            raise
        self.renderer.attach(self.world)
        self._closed = False
        try:
            self._camera_name = next((n for n in CAMERA_SENSORS if n in self.world.sensors), "")
            for d in cfg.disturbances:
                self.world.add_disturbance(d)
            streams = [f"disturbance.{i}" for i in range(len(cfg.disturbances))]
            if self.wind is not None:
                self.world.add_disturbance(self.wind)
                streams.append("wind")
            self.world.disturbance_streams = tuple(streams)
            self._state_id = p.saveState(physicsClientId=self.world.client)
        except BaseException:
            self.close()
            raise

    # -- gymnasium API -------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        """Start hovering above the deck.

        The start is drawn from the ``"start"`` stream: altitude ``start_altitude +-
        start_altitude_jitter`` above the deck origin, a horizontal offset uniform in
        ``+-start_offset`` per axis (m) and a yaw uniform in ``+-start_yaw`` (rad). With
        ``random_deck_start`` the deck's motion starts at a time uniform in [0, 130) s of its
        profile instead of at t = 0. ``options`` may fix ``altitude`` (m, in [0.3 m, the highest
        start allowed by arena_ceiling]), ``offset`` ((x, y) m, world), ``yaw`` (rad) and
        ``deck_time`` (s).
        """
        self._check_open()
        opts = dict(check_mapping("reset options", options)) if options is not None else {}
        super().reset(seed=seed)
        streams = SeedStreams.from_generator(self.np_random)
        alt, off, yaw, deck_time = self._draw_start(opts, streams.generator("start"))
        profile, checked = self._draw_deck(streams.generator("deck"), deck_time)
        self._profile = None  # no episode while the world is being reset (or if that fails)
        p.restoreState(stateId=self._state_id, physicsClientId=self.world.client)
        self.world.reset(
            profile,
            self.config.task.deck.horizon_s,
            altitude=alt,
            offset_xy=off,
            yaw=yaw,
            stroke_checked=checked,
        )
        self.world.reset_random(streams)
        if self.config.task.start.trimmed:
            self.world.trim(keep_view=self._trim_keeps_view())
        self._profile = profile
        self._episode_over = False
        self._last_touchdown = None
        obs = self._get_obs()
        info = self._get_info(self.world.sensing.snapshot())
        self.renderer.follow()
        return obs, info

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        a = self.begin_step(action)
        return self.end_step(a, self.world.step())

    def begin_step(self, action: Any) -> NDArray[np.float64]:
        """The first phase of :meth:`step`: check the env's state and ``action`` and hand the action
        to the autopilot or the motors (:meth:`apply_action`); returns it as floats. Then the world
        advances one control period (``world.step()``, which a vector env calls itself) and
        :meth:`end_step` finishes the step."""
        self._check_open()
        if self._profile is None:
            raise RuntimeError("call reset() before step()")
        if self._episode_over:
            raise RuntimeError("episode is over (terminated): call reset() before stepping again")
        return self.apply_action(action)

    def end_step(
        self, action: NDArray[np.float64], touchdown: Touchdown | None
    ) -> tuple[dict, float, bool, bool, dict]:
        """The last phase of :meth:`step`, once the world advanced one control period: the sensors
        read, the outcome, reward and info. ``action`` is what :meth:`begin_step` returned,
        ``touchdown`` the world's first contact in the period (None: none)."""
        if touchdown is not None and self._last_touchdown is None:
            self._last_touchdown = touchdown
        snap = self.world.sensing.snapshot()
        state, td = snap.task_state(), touchdown_arrays(touchdown)
        offset = self._tag_offset(snap)
        code = self._classify(state, td, offset)
        terminated = bool(tasks.is_terminal(code))
        self._episode_over = terminated
        obs = self._get_obs()
        reward, terms = self._get_rew(action, code, state, td, offset)
        info = self._get_info(snap)
        info.update(terms)
        info["outcome"] = tasks.outcome_name(code)
        info["crash_reason"] = tasks.describe(
            code, td, state, self.config.task.thresholds, self._success_radius
        )
        if touchdown is not None:
            info["touchdown"] = {
                "body": touchdown.body,
                "time": touchdown.time,
                "relative_vertical_speed": touchdown.relative_vertical_speed,
                "relative_tilt": touchdown.relative_tilt,
                "on_deck": touchdown.on_deck,
            }
        self.renderer.follow()
        return obs, reward, terminated, False, info

    def apply_action(self, action: Any) -> NDArray[np.float64]:
        """Check ``action`` and hand it to the autopilot (velocity setpoint) or the motors; returns
        it as floats (:meth:`begin_step` hands the step's action over with this)."""
        a = _check_action(action)
        if self.config.world.action_mode == "velocity":
            self.world.set_velocity_setpoint(a * self.max_velocity)
        else:
            self.world.set_motor_thrusts((a + 1.0) / 2.0)
        return a

    def render(self) -> NDArray[np.uint8] | None:
        """The chase view (H, W, 3) uint8 with ``render_mode="rgb_array"``, else None
        (:class:`~ihrcf_env.envs.render.EnvRenderer`)."""
        self._check_open()
        return self.renderer.render()

    def close(self) -> None:
        """Disconnect the physics client; safe to call twice. The env is unusable afterwards."""
        if getattr(self, "_closed", True):
            return
        self._closed = True
        self.renderer.release()
        self.world.close()

    # -- no copies: one env, one physics client -------------------------------------------
    def __copy__(self) -> NoReturn:
        raise TypeError(_NO_COPY)

    def __deepcopy__(self, memo: dict[int, Any]) -> NoReturn:
        raise TypeError(_NO_COPY)

    def __reduce_ex__(self, protocol: SupportsIndex) -> NoReturn:
        raise TypeError(_NO_COPY)

    def __getstate__(self) -> NoReturn:
        raise TypeError(_NO_COPY)

    # -- pieces --------------------------------------------------------------------------
    @property
    def max_velocity(self) -> NDArray[np.float64]:
        """Velocity action scale (m/s, m/s, m/s, rad/s)."""
        return np.asarray(self.config.task.max_velocity, dtype=np.float64)

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("env is closed (close() was called): make a new one with gym.make")

    def _draw_deck(self, rng: np.random.Generator, deck_time: float) -> tuple[MotionProfile, bool]:
        """This episode's deck motion from ``rng``, started at ``deck_time`` (s), and whether its
        stroke was checked over ``horizon_s`` here: :func:`ihrcf_env.tasks.episode.draw_deck` (a
        random sea the legs cannot follow is drawn again)."""
        return episode.draw_deck(self.config, rng, deck_time)

    def _trim_keeps_view(self) -> bool:
        """With ``start_trimmed``: move the trimmed drone so the camera still looks at the drawn
        point (the landing tasks, whose start keeps the tag in view)."""
        return False

    def _draw_start(
        self, options: dict[str, Any], rng: np.random.Generator
    ) -> tuple[float, tuple[float, float], float, float]:
        """(altitude m, offset (x, y) m, yaw rad, deck start time s) of a new episode: drawn from
        ``rng`` (always, so ``options`` do not shift the stream), then ``options``
        (:func:`ihrcf_env.tasks.episode.draw_start`)."""
        return tuple(episode.draw_start(self.config, rng, options))  # type: ignore[return-value]

    def _get_obs(self) -> dict[str, Any]:
        w = self.world
        r = w.sensing.read_sensors()
        obs: dict[str, Any] = {}
        if "image" in r:
            obs["image"] = r["image"]
        if "tag_corners" in r:
            self._tag_reason = str(r["tag_reason"])
            obs["tag_corners"] = clip(r["tag_corners"], -1.0, self._corner_bound).astype(np.float32)
            obs["tag_detected"] = int(bool(r["tag_detected"]))
            obs["tag_status"] = int(r["tag_status"])
        if self._camera_name:
            age = w.time - w.sensing.sample_times[self._camera_name]
            age = MAX_SENSOR_AGE if math.isnan(age) else age  # no frame yet (camera latency)
            obs["camera_age"] = np.array([min(max(age, 0.0), MAX_SENSOR_AGE)], np.float32)
            if w.sensing.camera_pipeline is not None:
                obs["camera_frame"] = np.array([w.sensing.frame_counts[self._camera_name]], np.int64)
        for name in w.sensing.clocks:  # sensors on their own clock: the age of the sample shown
            age = min(max(w.time - w.sensing.sample_times[name], 0.0), MAX_SENSOR_AGE)
            obs[f"{name}_age"] = np.array([age], np.float32)
        obs["ranges"] = clip(r["ranges"], 0.0, self._max_range).astype(np.float32)
        obs["ranges_valid"] = np.asarray(r["ranges_valid"], dtype=np.int8)
        obs["imu"] = {
            "quaternion": clip(r["quaternion"], -1.0, 1.0).astype(np.float32),
            "angular_velocity": clip(r["angular_velocity"], -50.0, 50.0).astype(np.float32),
            "linear_acceleration": clip(r["linear_acceleration"], -200.0, 200.0).astype(np.float32),
        }
        v = w.nav_velocity()
        obs["nav_velocity"] = clip(v, -MAX_NAV_VELOCITY, MAX_NAV_VELOCITY).astype(np.float32)
        for name in self.config.world.extra_sensors:
            for key, out in SENSORS[name].outputs.items():
                value = np.nan_to_num(np.asarray(r[key], np.float64), nan=out.low)
                obs[key] = clip(value, out.low, out.high).astype(np.float32).reshape(out.shape)
        return obs

    #: The landing tasks' success radius (m; None: the hover task has none), read by the rules.
    _success_radius: float | None = None

    _offset_memo: tuple[Snapshot | None, NDArray[np.float64]] = (None, np.zeros(()))

    def _tag_offset(self, s: Snapshot) -> NDArray[np.float64]:
        """:func:`ihrcf_env.tasks.tag_offset` of ``s`` (m; memoised on the snapshot, which the
        world shares until its state changes)."""
        if self._offset_memo[0] is not s:
            self._offset_memo = (s, tasks.tag_offset(s.task_state()))
        return self._offset_memo[1]

    def _classify(self, state: tasks.TaskState, touchdown: tasks.TouchdownState, offset: Any) -> int:
        """The step's outcome code (:data:`ihrcf_env.tasks.OUTCOME_NAMES`)."""
        task = self.config.task
        code = tasks.classify(state, touchdown, task.thresholds, task.arena, self._success_radius, offset)
        return int(code)

    def _get_rew(
        self,
        action: NDArray[np.float64],
        outcome: int,
        state: tasks.TaskState,
        touchdown: tasks.TouchdownState,
        offset: Any,
    ) -> tuple[float, dict[str, float]]:
        """The step's reward and its terms (``reward_<term>``): :func:`ihrcf_env.tasks.hover_reward`."""
        terms = tasks.hover_reward(state, action, np.asarray(outcome), self.config.task.reward, offset)
        return _reward_info(terms)

    def _get_info(self, s: Snapshot) -> dict[str, Any]:
        w = self.world
        contacts = w.contact_bodies()
        info: dict[str, Any] = {"time": w.time}
        if self._camera_name:
            info["camera_time"] = w.sensing.sample_times[self._camera_name]
            info["camera_age"] = w.time - info["camera_time"]
            if self.config.world.camera_output == "corners":
                info["tag_reason"] = self._tag_reason
        # copies: the snapshot's arrays are read-only and shared (Sensing.snapshot is memoised)
        return info | {
            "deck_position_body": s.deck_position_body.copy(),
            "deck_euler_body": euler_from_matrix(s.deck_rotation_body),
            "deck_rotation_body": s.deck_rotation_body.copy(),
            "drone_position_world": s.drone_position.copy(),
            "drone_quaternion_world": s.drone_quaternion.copy(),
            "deck_position_world": s.deck_position.copy(),
            "deck_quaternion_world": quat_from_matrix(s.deck_rotation),
            "leg_lengths": w.deck.geometry.leg_lengths(s.deck_position, s.deck_rotation),
            "contact_deck": w.deck.body in contacts,
            "contact_ground": w.ground in contacts or w.deck.base_body in contacts,
            "wind_velocity": self.wind.velocity(w.time) if self.wind is not None else np.zeros(3),
            "relative_velocity": s.relative_velocity.copy(),
        }

    # -- conveniences for tools ---------------------------------------------------------
    @property
    def rig(self) -> SensorRig:
        return self.config.world.rig

    @property
    def camera_config(self) -> CameraConfig | None:
        return self.config.world.camera

    def drone_state(self) -> DroneState:
        """Ground truth of the drone now (:class:`DroneState`: world frame, body rates in the body
        frame), for tools that report it as an autopilot would (e.g. :mod:`ihrcf_env.mavlink`)."""
        self._check_open()
        pos, quat, vel, ang = self.world.quad.state()
        q = np.array(quat, dtype=np.float64)
        rates = matrix_from_quat(q).T @ np.array(ang, dtype=np.float64)
        return DroneState(
            self.world.time, np.array(pos, dtype=np.float64), q, np.array(vel, dtype=np.float64), rates
        )

    def deck_pose_body(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ground-truth deck (position m, euler rad) in the body frame."""
        self._check_open()
        s = self.world.sensing.snapshot()
        return s.deck_position_body.copy(), euler_from_matrix(s.deck_rotation_body)


class DroneState(NamedTuple):
    """The drone's true state at simulated ``time`` (s): ``position`` (m) and ``velocity`` (m/s)
    in the world frame, ``quaternion`` (x, y, z, w, world from body) and the body ``rates`` (rad/s,
    body frame FLU)."""

    time: float
    position: NDArray[np.float64]
    quaternion: NDArray[np.float64]
    velocity: NDArray[np.float64]
    rates: NDArray[np.float64]


def _reward_info(terms: tuple[Any, ...]) -> tuple[float, dict[str, float]]:
    """(reward, ``{"reward_<term>": value}``) of one env's reward terms (a NamedTuple of 0-d arrays)."""
    values = {f"reward_{name}": float(v) for name, v in zip(terms._fields, terms, strict=True)}  # type: ignore[attr-defined]
    return float(tasks.total(tuple(values.values()))), values


def _check_action(action: Any) -> NDArray[np.float64]:
    """The action as 4 finite float64 values clipped to [-1, 1]; ValueError / TypeError naming
    ``action`` otherwise (complex, strings, objects and NaN/inf are refused, not cast)."""
    a = np.asarray(action)
    if a.dtype.kind not in "biuf":
        raise TypeError(f"action must be 4 real numbers, got an array of {a.dtype} {action!r}")
    if a.shape != (4,):
        raise ValueError(f"action must have shape (4,), got {a.shape}")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise ValueError(f"action contains NaN or inf: {a.tolist()}")
    return clip(a, -1.0, 1.0)


def _observation_space(world: WorldConfig) -> spaces.Dict:
    obs: dict[str, spaces.Space] = {}
    cam = world.camera
    if cam is not None and world.camera_output == "image":
        obs["image"] = spaces.Box(0, 255, (cam.height, cam.width, 3), np.uint8)
    elif cam is not None:
        bound = np.float32(max(cam.width, cam.height))
        obs["tag_corners"] = spaces.Box(np.float32(-1.0), bound, (4, 2), np.float32)
        obs["tag_detected"] = spaces.Discrete(2)
        obs["tag_status"] = spaces.Discrete(len(TAG_STATUS))
    if cam is not None:
        obs["camera_age"] = spaces.Box(np.float32(0.0), np.float32(MAX_SENSOR_AGE), (1,), np.float32)
        if cam.latency > 0:  # frames delivered this episode (a new frame: the count changed)
            obs["camera_frame"] = spaces.Box(0, np.iinfo(np.int64).max, (1,), np.int64)
    for name, rate in (("tof", world.tof.rate_hz), ("imu", world.imu.rate_hz)):
        if rate is not None:  # sensors on their own clock: the age of the sample shown
            obs[f"{name}_age"] = spaces.Box(np.float32(0.0), np.float32(MAX_SENSOR_AGE), (1,), np.float32)
    obs["ranges"] = spaces.Box(np.float32(0.0), np.float32(world.tof.max_range), (4,), np.float32)
    obs["ranges_valid"] = spaces.MultiBinary(4)
    obs["imu"] = spaces.Dict(
        {
            "quaternion": spaces.Box(-1.0, 1.0, (4,), np.float32),
            "angular_velocity": spaces.Box(-50.0, 50.0, (3,), np.float32),
            "linear_acceleration": spaces.Box(-200.0, 200.0, (3,), np.float32),
        }
    )
    obs["nav_velocity"] = spaces.Box(-MAX_NAV_VELOCITY, MAX_NAV_VELOCITY, (3,), np.float32)
    for name in world.extra_sensors:
        for key, out in SENSORS[name].outputs.items():
            obs[key] = spaces.Box(np.float32(out.low), np.float32(out.high), out.shape, np.float32)
    return spaces.Dict(obs)
