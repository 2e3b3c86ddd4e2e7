"""``DeckLandingEnv``: land a quadrotor on a moving Stewart-platform deck.

Observation (``gymnasium.spaces.Dict``):

================  =======================  =====================================================
key               shape / dtype            meaning
================  =======================  =====================================================
``image``         (H, W, 3) uint8          downward camera, TinyRenderer (absent if camera=False)
``ranges``        (4,) float32, m          ToF ps1..ps4 along the optical axis, in [0, max_range]
``ranges_valid``  (4,) int8                1 = valid reading; invalid readings read max_range
``imu``           Dict                     ``quaternion`` (4,) x, y, z, w world-from-body;
                                           ``angular_velocity`` (3,) rad/s body frame;
                                           ``linear_acceleration`` (3,) m/s^2 specific force, body
================  =======================  =====================================================

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
Truncation only by ``max_episode_steps`` (TimeLimit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p
from gymnasium import spaces
from numpy.typing import NDArray

from ihrcf_env.core.frames import euler_from_matrix, quat_from_matrix
from ihrcf_env.core.profiles import PAPER_DURATION, MotionProfile, ShiftedProfile, make_profile
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.sim.deck import DeckConfig
from ihrcf_env.sim.sensors import CameraConfig, ToFConfig
from ihrcf_env.sim.world import ACTION_MODES, Snapshot, Touchdown, World, WorldConfig

SUCCESS_SPEED = 0.5  # m/s
SUCCESS_TILT = math.radians(10.0)
CRASH_TILT = math.radians(60.0)
DEFAULT_HORIZON_S = 600.0


class DeckLandingEnv(gym.Env):
    """Quadrotor landing on a 6-DOF Stewart deck, sensed by a downward camera and four ToF beams.

    Frames and conventions: see :mod:`ihrcf_env.core.frames`. Ground truth is in ``info``: the deck
    pose in the drone body frame (``deck_position_body`` m, ``deck_euler_body`` roll/pitch/yaw rad),
    world poses of drone and deck, the six leg lengths and contact flags.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 20}

    def __init__(
        self,
        render_mode: str | None = None,
        action_mode: str = "velocity",
        control_hz: int = 20,
        deck_profile: str | Callable[[float], Any] | MotionProfile = "paper",
        sea_state_amplitudes: Mapping[str, float] | None = None,
        random_deck_start: bool = False,
        camera: bool = True,
        camera_width: int = 512,
        camera_height: int = 512,
        camera_fov: float = math.radians(60.0),
        camera_distortion: tuple[float, float] = (0.0, 0.0),
        tof_noise: str = "ideal",
        tof_max_range: float = 4.0,
        tag_id: int = 0,
        tag_size: float = 0.4,
        start_altitude: float = 1.0,
        start_altitude_jitter: float = 0.05,
        start_offset: float = 0.1,
        start_yaw: float = 0.2,
        max_velocity: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
        arena_half_width: float = 5.0,
        arena_ceiling: float = 6.0,
        horizon_s: float | None = None,
        chase_size: tuple[int, int] = (640, 480),
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        if action_mode not in ACTION_MODES:
            raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
        if isinstance(deck_profile, str) and deck_profile not in ("paper", "sea_state", "static"):
            raise ValueError(
                f"deck_profile must be 'paper', 'sea_state', 'static' or a callable, got {deck_profile!r}"
            )
        if not isinstance(deck_profile, str | MotionProfile) and not callable(deck_profile):
            raise ValueError(
                f"deck_profile must be a name or a callable t -> pose, got {type(deck_profile).__name__}"
            )
        for name, val in (
            ("start_altitude", start_altitude),
            ("arena_half_width", arena_half_width),
            ("arena_ceiling", arena_ceiling),
        ):
            if not (math.isfinite(val) and val > 0):
                raise ValueError(f"{name} must be positive, got {val!r}")
        for name, val in (
            ("start_altitude_jitter", start_altitude_jitter),
            ("start_offset", start_offset),
            ("start_yaw", start_yaw),
        ):
            if not (math.isfinite(val) and val >= 0):
                raise ValueError(f"{name} must be >= 0, got {val!r}")
        mv = np.asarray(max_velocity, dtype=np.float64)
        if mv.shape != (4,) or not np.all(np.isfinite(mv)) or np.any(mv <= 0):
            raise ValueError(
                f"max_velocity must be 4 positive numbers (m/s, m/s, m/s, rad/s), got {max_velocity!r}"
            )
        if horizon_s is not None and not (math.isfinite(horizon_s) and horizon_s > 0):
            raise ValueError(f"horizon_s must be positive (s), got {horizon_s!r}")

        cam_cfg = None
        if camera:
            k = np.asarray(camera_distortion, dtype=np.float64)
            if k.shape != (2,):
                raise ValueError(f"camera_distortion must be (k1, k2), got {camera_distortion!r}")
            cam_cfg = CameraConfig(
                width=camera_width,
                height=camera_height,
                fov=camera_fov,
                distortion=(float(k[0]), float(k[1])),
            )
        self.config = WorldConfig(
            control_hz=control_hz,
            camera=cam_cfg,
            tof=ToFConfig(max_range=tof_max_range, noise=tof_noise),
            deck=DeckConfig(tag_id=tag_id, tag_size=tag_size),
            action_mode=action_mode,
        )
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": control_hz}
        self.deck_profile = deck_profile
        self.sea_state_amplitudes = dict(sea_state_amplitudes) if sea_state_amplitudes is not None else None
        if isinstance(deck_profile, str) and deck_profile == "sea_state":
            make_profile(
                "sea_state", np.random.default_rng(0), self.sea_state_amplitudes
            )  # validate amplitudes now
        self.start_altitude = float(start_altitude)
        self.start_altitude_jitter = float(start_altitude_jitter)
        self.start_offset = float(start_offset)
        self.start_yaw = float(start_yaw)
        self.max_velocity = mv
        self.arena_half_width = float(arena_half_width)
        self.arena_ceiling = float(arena_ceiling)
        self.horizon_s = horizon_s
        self.random_deck_start = bool(random_deck_start)
        self.chase_size = (int(chase_size[0]), int(chase_size[1]))

        tof_max = np.float32(tof_max_range)
        obs: dict[str, spaces.Space] = {}
        if cam_cfg is not None:
            obs["image"] = spaces.Box(0, 255, (camera_height, camera_width, 3), np.uint8)
        obs["ranges"] = spaces.Box(np.float32(0.0), tof_max, (4,), np.float32)
        obs["ranges_valid"] = spaces.MultiBinary(4)
        obs["imu"] = spaces.Dict(
            {
                "quaternion": spaces.Box(-1.0, 1.0, (4,), np.float32),
                "angular_velocity": spaces.Box(-50.0, 50.0, (3,), np.float32),
                "linear_acceleration": spaces.Box(-200.0, 200.0, (3,), np.float32),
            }
        )
        self.observation_space = spaces.Dict(obs)
        self.action_space = spaces.Box(-1.0, 1.0, (4,), np.float32)

        self.world = World(self.config, gui=render_mode == "human")
        self._state_id = p.saveState(physicsClientId=self.world.client)
        self._profile: MotionProfile | None = None

    # -- gymnasium API -------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        """Start hovering above the deck.

        The start is drawn from ``np_random``: altitude ``start_altitude +- start_altitude_jitter``
        above the deck origin, a horizontal offset uniform in ``+-start_offset`` per axis (m) and a
        yaw uniform in ``+-start_yaw`` (rad). With ``random_deck_start`` the deck's motion starts at a
        time uniform in [0, 130) s of its profile instead of at t = 0. ``options`` may fix
        ``altitude`` (m), ``offset`` ((x, y) m, world), ``yaw`` (rad) and ``deck_time`` (s).
        """
        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"altitude", "offset", "yaw", "deck_time"}
        if unknown:
            raise ValueError(
                f"reset options has unknown keys {sorted(unknown)}; known: altitude, offset, yaw, deck_time"
            )
        rng = self.np_random
        alt = self.start_altitude + rng.uniform(-1, 1) * self.start_altitude_jitter
        off = rng.uniform(-1, 1, 2) * self.start_offset
        yaw = rng.uniform(-1, 1) * self.start_yaw
        if "altitude" in options:
            alt = float(options["altitude"])
            if not (math.isfinite(alt) and 0.15 < alt < self.arena_ceiling):
                raise ValueError(
                    f"options['altitude'] must be in (0.15, {self.arena_ceiling}) m, got {alt!r}"
                )
        if "offset" in options:
            off = np.asarray(options["offset"], dtype=np.float64)
            if off.shape != (2,) or not np.all(np.isfinite(off)):
                raise ValueError(f"options['offset'] must be 2 finite numbers (m), got {options['offset']!r}")
        if "yaw" in options:
            yaw = float(options["yaw"])
            if not math.isfinite(yaw):
                raise ValueError(f"options['yaw'] must be finite (rad), got {yaw!r}")

        deck_time = rng.uniform(0.0, PAPER_DURATION) if self.random_deck_start else 0.0
        if "deck_time" in options:
            deck_time = float(options["deck_time"])
            if not (math.isfinite(deck_time) and deck_time >= 0):
                raise ValueError(f"options['deck_time'] must be a finite time >= 0 (s), got {deck_time!r}")
        profile = make_profile(self.deck_profile, rng, self.sea_state_amplitudes)
        self._profile = ShiftedProfile(profile, deck_time) if deck_time else profile
        p.restoreState(stateId=self._state_id, physicsClientId=self.world.client)
        self.world.reset(
            self._profile, self._horizon(), altitude=alt, offset_xy=(float(off[0]), float(off[1])), yaw=yaw
        )
        self._last_touchdown: Touchdown | None = None
        obs = self._get_obs()
        info = self._get_info(self.world.snapshot())
        if self.render_mode == "human":
            self._update_gui_camera()
        return obs, info

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (4,):
            raise ValueError(f"action must have shape (4,), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action contains NaN or inf: {a.tolist()}")
        if self._profile is None:
            raise RuntimeError("call reset() before step()")
        a = np.clip(a, -1.0, 1.0)
        if self.config.action_mode == "velocity":
            self.world.set_velocity_setpoint(a * self.max_velocity)
        else:
            self.world.set_motor_thrusts((a + 1.0) / 2.0)
        touchdown = self.world.step()
        if touchdown is not None and self._last_touchdown is None:
            self._last_touchdown = touchdown
        snap = self.world.snapshot()
        outcome, reason = self._outcome(touchdown, snap)
        terminated = outcome != "flying"
        obs = self._get_obs()
        reward, terms = self._get_rew(a, outcome, snap)
        info = self._get_info(snap)
        info.update(terms)
        info["outcome"] = outcome
        info["crash_reason"] = reason
        if touchdown is not None:
            info["touchdown"] = {
                "body": touchdown.body,
                "time": touchdown.time,
                "relative_vertical_speed": touchdown.relative_vertical_speed,
                "relative_tilt": touchdown.relative_tilt,
                "on_deck": touchdown.on_deck,
            }
        if self.render_mode == "human":
            self._update_gui_camera()
        return obs, reward, terminated, False, info

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode == "rgb_array":
            return self._chase_view()
        return None

    def close(self) -> None:
        if getattr(self, "world", None) is not None:
            self.world.close()

    # -- pieces --------------------------------------------------------------------------
    def _horizon(self) -> float:
        """Seconds over which reset checks the deck profile against the legs' stroke."""
        return self.horizon_s if self.horizon_s is not None else DEFAULT_HORIZON_S

    def _get_obs(self) -> dict[str, Any]:
        w = self.world
        ranges, valid = w.read_tof(self.np_random)
        imu = w.imu()
        obs: dict[str, Any] = {}
        if w.camera is not None:
            obs["image"] = w.render_camera()
        obs["ranges"] = ranges
        obs["ranges_valid"] = valid
        obs["imu"] = {
            "quaternion": np.clip(imu["quaternion"], -1, 1).astype(np.float32),
            "angular_velocity": np.clip(imu["angular_velocity"], -50, 50).astype(np.float32),
            "linear_acceleration": np.clip(imu["acceleration"], -200, 200).astype(np.float32),
        }
        return obs

    def _outcome(self, touchdown: Touchdown | None, s: Snapshot) -> tuple[str, str]:
        """("flying" | "success" | "crash", reason)."""
        if touchdown is not None:
            if touchdown.body != "deck":
                return "crash", f"hit the {touchdown.body}"
            if not touchdown.on_deck:
                return "crash", "touched down outside the deck"
            if abs(touchdown.relative_vertical_speed) >= SUCCESS_SPEED:
                return (
                    "crash",
                    f"vertical speed {abs(touchdown.relative_vertical_speed):.2f} m/s at touchdown",
                )
            if touchdown.relative_tilt >= SUCCESS_TILT:
                return "crash", f"tilt {math.degrees(touchdown.relative_tilt):.1f} deg at touchdown"
            return "success", ""
        pos, R = s.drone_position, s.drone_rotation
        if math.acos(max(-1.0, min(1.0, R[2, 2]))) > CRASH_TILT:
            return "crash", "tilt over 60 deg"
        if (
            abs(pos[0]) > self.arena_half_width
            or abs(pos[1]) > self.arena_half_width
            or pos[2] > self.arena_ceiling
        ):
            return "crash", "left the arena"
        return "flying", ""

    def _get_rew(
        self, action: NDArray[np.float64], outcome: str, s: Snapshot
    ) -> tuple[float, dict[str, float]]:
        e = s.drone_position - s.deck_position
        terms = {
            "reward_position": -math.hypot(e[0], e[1]) - 0.2 * max(float(e[2]), 0.0),
            "reward_velocity": -0.1 * float(np.linalg.norm(s.relative_velocity)),
            "reward_attitude": -0.1 * s.relative_tilt,
            "reward_action": -0.01 * float(action @ action),
            "reward_terminal": 100.0 if outcome == "success" else (-100.0 if outcome == "crash" else 0.0),
        }
        return float(sum(terms.values())), terms

    def _get_info(self, s: Snapshot) -> dict[str, Any]:
        w = self.world
        contacts = w.contact_bodies()
        return {
            "time": w.time,
            "deck_position_body": s.deck_position_body,
            "deck_euler_body": euler_from_matrix(s.deck_rotation_body),
            "deck_rotation_body": s.deck_rotation_body,
            "drone_position_world": s.drone_position,
            "drone_quaternion_world": s.drone_quaternion,
            "deck_position_world": s.deck_position,
            "deck_quaternion_world": quat_from_matrix(s.deck_rotation),
            "leg_lengths": w.deck.geometry.leg_lengths(s.deck_position, s.deck_rotation),
            "contact_deck": w.deck.body in contacts,
            "contact_ground": w.ground in contacts or w.deck.base_body in contacts,
        }

    # -- rendering -----------------------------------------------------------------------
    def _chase_view(self) -> NDArray[np.uint8]:
        from ihrcf_env.sim.sensors import render_rgb

        w = self.world
        w.deck.update_visuals()
        pos, R = w.drone_pose()
        deck_pos, _ = w.deck.pose()
        target = 0.5 * (pos + deck_pos) - np.array([0.0, 0.0, 0.35])
        yaw = math.atan2(R[1, 0], R[0, 0])
        back = np.array([-math.cos(yaw), -math.sin(yaw), 0.0])
        side = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
        eye = target + 2.5 * back + 0.8 * side + np.array([0.0, 0.0, 1.0])
        cid = w.client
        view = p.computeViewMatrix(eye.tolist(), target.tolist(), [0, 0, 1], physicsClientId=cid)
        width, height = self.chase_size
        proj = p.computeProjectionMatrixFOV(50.0, width / height, 0.05, 30.0, physicsClientId=cid)
        cfg = CameraConfig(width=width, height=height)
        return render_rgb(cid, cfg, view, proj)

    def _update_gui_camera(self) -> None:
        self.world.deck.update_visuals()
        pos, _ = self.world.drone_pose()
        p.resetDebugVisualizerCamera(2.5, 30.0, -25.0, pos.tolist(), physicsClientId=self.world.client)

    # -- conveniences for tools ---------------------------------------------------------
    @property
    def rig(self) -> SensorRig:
        return self.config.rig

    @property
    def camera_config(self) -> CameraConfig | None:
        return self.config.camera

    def deck_pose_body(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ground-truth deck (position m, euler rad) in the body frame."""
        s = self.world.snapshot()
        return s.deck_position_body, euler_from_matrix(s.deck_rotation_body)
