"""``DeckLandingV1Env``: the landing task of ``ihrcf_env/DeckLanding-v1``, where sensing matters.

A :class:`~ihrcf_env.envs.deck_landing.DeckLandingEnv` (same world, actions, sensors, options) with
the landing goal of :class:`~ihrcf_env.config.task.LandingGoal`; its defaults differ from the
hover task's (:data:`V1_DEFAULTS`):

* **start** 1.5-3 m above the deck origin (``start_altitude`` 2.25 +- 0.75 m), any yaw
  (``start_yaw`` pi), a horizontal offset uniform over a disc of radius ``start_offset`` (1 m)
  clipped so that the tag (with its white border) stays in the camera's view at the drawn altitude
  (:meth:`DeckLandingV1Env.start_radius`: 0.40 m at 1.5 m, the full 1 m from 2.55 m up): the
  policy sees the tag from the first step;
* the deck on the ``"sea_state"`` profile from a seeded random time; ``sensor_preset="realistic"``;
* **wind** on (:class:`~ihrcf_env.sim.disturbances.Wind`: 0-5 m/s mean plus Dryden gusts);
* **success** = a touchdown on the deck with relative vertical speed < 0.5 m/s, relative tilt
  < 10 deg **and** the drone's centre within ``success_radius`` (0.15 m) of the tag centre,
  horizontally (measured at the end of the control step of the touchdown). Any other touchdown, a
  tilt over 60 deg or leaving the arena is a crash (``info["crash_reason"]``). Both terminate; only
  the ``TimeLimit`` truncates.

**Reward** (weights :class:`~ihrcf_env.config.task.RewardWeightsV1`, per step, each term in
``info["reward_<term>"]``)::

    progress = Phi(s') - Phi(s)        Phi = -(distance d_xy + height h + speed |v_rel|)
    time     = -time / control_hz
    action   = -action |a|^2 / control_hz
    terminal = +success on success; on a failed touchdown on the deck (too fast, too tilted or off
               the tag, but on the deck) -near_miss - (crash - near_miss) * min(1, miss - 1), with
               miss = max(speed / 0.5 m/s, tilt / 10 deg, offset / success_radius) (>= 1 on a
               failure): a touchdown just outside the limits costs near_miss, twice the limits
               or worse the full crash; -crash on any other failure (ground, tilt, arena)

with ``d_xy`` the horizontal distance drone centre - tag centre (m), ``h`` the drone's height above
the deck origin less the 0.10 m of its legs (m, >= 0) and ``|v_rel|`` the speed relative to the
deck (m/s; at touchdown the approach speed along the deck normal). The progress term is
potential-based shaping (Ng, Harada & Russell 1999; the design of Gymnasium's LunarLander): over an
episode it sums to ``Phi(last) - Phi(start)``, bounded (about 20 with the defaults), so the
terminal terms decide the order of returns. The time cost (1/s, -30 over a 30 s episode) makes
hovering clearly worse than landing, and the graded near-miss penalty gives a learner a gradient
from its first soft, off-target touchdowns towards the target (with one flat -100 for every
failure, a learner must succeed in ~40 % of its attempts before trying beats hovering: PPO settled
on hovering). The order success > hover > crash still holds with fixed policies (test).

The outcome and the reward are :func:`ihrcf_env.tasks.classify` (with ``success_radius``) and
:func:`ihrcf_env.tasks.landing_reward`. ``info`` adds ``tag_offset`` (m, horizontal) and
``is_success`` to the ground truth of the hover task's ``info`` (which has ``wind_velocity`` and
``relative_velocity``, world, m/s). The observation is the raw env's; ``ihrcf_env/DeckLanding-v1``
wraps it (:mod:`ihrcf_env.wrappers.landing_obs`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env import tasks
from ihrcf_env.config.make import TASK_DEFAULTS
from ihrcf_env.config.task import LandingGoal
from ihrcf_env.envs.deck_landing import DeckLandingEnv, _reward_info
from ihrcf_env.sim.sensing import Snapshot
from ihrcf_env.sim.world import Touchdown, touchdown_arrays
from ihrcf_env.tasks import episode

#: ``gym.make`` defaults of v1 that differ from the hover task's (any of them can still be given).
V1_DEFAULTS: dict[str, Any] = TASK_DEFAULTS["landing-v1"]
#: Legs below the drone's centre (m): the height of the centre above the deck when landed.
LEG_LENGTH = tasks.LEG_LENGTH
#: Half of the tag's printed extent around its centre (m) per metre of ``tag_size``: the black
#: square (8 cells) plus the one-cell white border the detector needs, i.e. 10/8 / 2.
TAG_EXTENT = episode.TAG_EXTENT


class DeckLandingV1Env(DeckLandingEnv):
    """The v1 landing task (module docstring). ``config`` (or options validated by
    :func:`~ihrcf_env.config.make.make_config` with ``task="landing-v1"``, v1 defaults in
    :data:`V1_DEFAULTS`); ``self.goal`` is the config's
    :class:`~ihrcf_env.config.task.LandingGoal`, ``self.wind`` the env's wind (None when
    calm)."""

    task_name = "landing-v1"

    def __init__(self, config: Any = None, **options: Any) -> None:
        self._closed = True  # until the parent has a world
        super().__init__(config, **options)
        goal = self.config.task.landing
        if goal is None:
            self.close()
            raise ValueError('DeckLandingV1Env needs a landing-task config (make_config(task="landing-v1"))')
        self.goal: LandingGoal = goal
        self._success_radius = goal.success_radius
        self._phi = 0.0

    # -- start -------------------------------------------------------------------------------
    def start_radius(self, altitude: float) -> float:
        """Largest start offset (m) at ``altitude`` (m above the deck origin): ``start_offset``, or
        less so that the tag and its white border stay ``view_margin`` inside the image whatever the
        yaw (the inscribed circle of the view); 0 if even a centred start cannot see it
        (:func:`ihrcf_env.tasks.episode.start_radius`)."""
        return episode.start_radius(self.config, altitude)

    def _draw_start(
        self, options: dict[str, Any], rng: np.random.Generator
    ) -> tuple[float, tuple[float, float], float, float]:
        """The hover task's draw (altitude, yaw, deck time and option checks), then the offset over
        the disc of :meth:`start_radius` (uniform in area) unless ``options["offset"]`` fixes it
        (:func:`ihrcf_env.tasks.episode.draw_start` with ``disc``)."""
        return tuple(episode.draw_start(self.config, rng, options, disc=True))  # type: ignore[return-value]

    def _trim_keeps_view(self) -> bool:
        return self.goal.start_in_view and self.config.world.camera is not None

    # -- episode -----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        obs, info = super().reset(seed=seed, options=options)
        self._phi = self.potential(self.world.sensing.snapshot())
        info["is_success"] = False
        return obs, info

    def end_step(
        self, action: NDArray[np.float64], touchdown: Touchdown | None
    ) -> tuple[dict, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = super().end_step(action, touchdown)
        info["is_success"] = info["outcome"] == "success"
        return obs, reward, terminated, truncated, info

    @staticmethod
    def tag_offset(s: Snapshot) -> float:
        """Horizontal distance (m) of the drone's centre from the tag centre (the deck origin):
        :func:`ihrcf_env.tasks.tag_offset`."""
        return float(tasks.tag_offset(s.task_state()))

    def potential(self, s: Snapshot, touchdown: Touchdown | None = None) -> float:
        """Shaping potential Phi (module docstring) of the state ``s``; after a ``touchdown`` its
        approach speed stands for the speed (the contact has already changed the velocity):
        :func:`ihrcf_env.tasks.landing_potential`."""
        td = touchdown_arrays(touchdown) if touchdown is not None else None
        return float(tasks.landing_potential(s.task_state(), self.goal.reward, td))

    def _get_rew(
        self,
        action: NDArray[np.float64],
        outcome: int,
        state: tasks.TaskState,
        touchdown: tasks.TouchdownState,
        offset: Any,
    ) -> tuple[float, dict[str, float]]:
        """The step's reward and its terms: :func:`ihrcf_env.tasks.landing_reward`."""
        terms, phi = tasks.landing_reward(
            state,
            action,
            np.asarray(outcome),
            touchdown,
            np.asarray(self._phi),
            self.goal.reward,
            self.config.task.thresholds,
            self.goal.success_radius,
            1.0 / self.config.world.control_hz,
            offset,
        )
        self._phi = float(phi)
        return _reward_info(terms)

    def miss(self, s: Snapshot) -> float:
        """How far the touchdown missed the success limits: max of speed, tilt and offset each over
        its limit (< 1: success); inf without a touchdown on the deck (:func:`ihrcf_env.tasks.miss`)."""
        td = touchdown_arrays(self._last_touchdown)
        th = self.config.task.thresholds
        return float(tasks.miss(s.task_state(), td, th, self.goal.success_radius))

    def failure_penalty(self, s: Snapshot) -> float:
        """The penalty (> 0) of a failed episode: graded by :meth:`miss` for a touchdown on the deck,
        the full ``crash`` weight otherwise (module docstring; :func:`ihrcf_env.tasks.failure_penalty`)."""
        return float(tasks.failure_penalty(np.asarray(self.miss(s)), self.goal.reward))

    def _get_info(self, s: Snapshot) -> dict[str, Any]:
        info = super()._get_info(s)
        info["tag_offset"] = float(self._tag_offset(s))
        return info


class DeckLandingV2Env(DeckLandingV1Env):
    """The landing task of ``ihrcf_env/DeckLanding-v2``: v1's goal, start, reward and outcomes in
    the conditions real deck landings face, graded by ``level`` (``"calm"``, ``"moderate"``,
    ``"rough"``; :mod:`ihrcf_env.config.levels`): a ship's deck in a WMO sea state, wind with gusts,
    the wind-holding autopilot and ground effect."""

    task_name = "landing-v2"
