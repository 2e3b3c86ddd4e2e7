"""Reward terms of the deck-landing tasks.

Pure functions of :class:`~ihrcf_env.tasks.state.TaskState` arrays, the action and the outcome
code (:mod:`ihrcf_env.tasks.outcome`), written against the inputs' array namespace (numpy or
``jax.numpy``), elementwise over any leading batch axes, without Python branching on array values.
Each reward function returns its terms (a NamedTuple of arrays, one field per ``info["reward_<
name>"]``); :func:`total` adds them in field order.
"""

from __future__ import annotations

from typing import Any, NamedTuple, Protocol

from ihrcf_env.tasks._math import dot3, hypot, namespace, norm3
from ihrcf_env.tasks.outcome import SUCCESS, ThresholdsLike, is_crash, relative_tilt, tag_offset
from ihrcf_env.tasks.state import CONTACT_DECK, TaskState, TouchdownState

__all__ = [
    "LEG_LENGTH",
    "HoverRewardTerms",
    "HoverWeightsLike",
    "LandingRewardTerms",
    "LandingWeightsLike",
    "action_cost",
    "failure_penalty",
    "hover_reward",
    "landing_potential",
    "landing_reward",
    "miss",
    "total",
]

#: Legs below the drone's centre (m): the height of the centre above the deck when landed.
LEG_LENGTH = 0.10


class HoverWeightsLike(Protocol):
    """The hover reward's weights (:class:`~ihrcf_env.envs.task_config.RewardWeights`)."""

    @property
    def position_xy(self) -> float: ...  # 1/m
    @property
    def position_z(self) -> float: ...  # 1/m
    @property
    def velocity(self) -> float: ...  # s/m
    @property
    def attitude(self) -> float: ...  # 1/rad
    @property
    def action(self) -> float: ...
    @property
    def success(self) -> float: ...
    @property
    def crash(self) -> float: ...


class LandingWeightsLike(Protocol):
    """The landing reward's weights (:class:`~ihrcf_env.envs.task_config.RewardWeightsV1`)."""

    @property
    def distance(self) -> float: ...  # 1/m
    @property
    def height(self) -> float: ...  # 1/m
    @property
    def speed(self) -> float: ...  # s/m
    @property
    def time(self) -> float: ...  # 1/s
    @property
    def action(self) -> float: ...  # 1/s
    @property
    def success(self) -> float: ...
    @property
    def crash(self) -> float: ...
    @property
    def near_miss(self) -> float: ...


class HoverRewardTerms(NamedTuple):
    """Terms of the hover task's reward (each of the batch shape)."""

    position: Any
    velocity: Any
    attitude: Any
    action: Any
    terminal: Any


class LandingRewardTerms(NamedTuple):
    """Terms of the landing tasks' reward (each of the batch shape)."""

    progress: Any
    time: Any
    action: Any
    terminal: Any


def total(terms: tuple[Any, ...]) -> Any:
    """The reward: the terms added left to right (``0.0 + t0 + t1 + ...``)."""
    out = 0.0
    for t in terms:
        out = out + t
    return out


def action_cost(action: Any) -> Any:
    """``|a|^2`` of the ``(..., 4)`` action, added left to right."""
    return dot3(action, action) + action[..., 3] * action[..., 3]


def hover_reward(
    state: TaskState, action: Any, outcome: Any, weights: HoverWeightsLike, offset: Any = None
) -> HoverRewardTerms:
    """The hover task's reward terms: ``position = -position_xy |e_xy| - position_z max(e_z, 0)``
    (e = drone minus deck origin, m), ``velocity = -velocity |v_rel|`` (drone minus deck point,
    m/s), ``attitude = -attitude tilt`` (drone z to deck normal, rad), ``action = -action |a|^2``
    and ``terminal = +success`` on a success, ``-crash`` on a crash, else 0. ``offset``:
    :func:`~ihrcf_env.tasks.outcome.tag_offset` of ``state`` (``|e_xy|``) if already computed."""
    xp = namespace(state.drone_position, action)
    e = state.drone_position - state.deck_position
    offset = hypot(xp, e[..., 0], e[..., 1]) if offset is None else offset
    position = -weights.position_xy * offset - weights.position_z * xp.maximum(e[..., 2], 0.0)
    v_rel = state.drone_velocity - state.deck_point_velocity
    terminal = xp.where(outcome == SUCCESS, weights.success, xp.where(is_crash(outcome), -weights.crash, 0.0))
    return HoverRewardTerms(
        position=position,
        velocity=-weights.velocity * norm3(xp, v_rel),
        attitude=-weights.attitude * relative_tilt(state.drone_rotation, state.deck_rotation),
        action=-weights.action * action_cost(action),
        terminal=terminal,
    )


def landing_potential(
    state: TaskState,
    weights: LandingWeightsLike,
    touchdown: TouchdownState | None = None,
    offset: Any = None,
) -> Any:
    """Shaping potential ``Phi = -(distance d_xy + height h + speed |v|)``: ``d_xy`` the tag offset
    (m), ``h`` the drone's height above the deck origin less :data:`LEG_LENGTH` (m, >= 0), ``|v|``
    the speed relative to the deck point (m/s), or where ``touchdown`` has a contact its approach
    speed along the deck normal (the contact has already changed the velocity). ``offset``:
    :func:`~ihrcf_env.tasks.outcome.tag_offset` of ``state`` if already computed."""
    xp = namespace(state.drone_position, state.deck_position)
    height = xp.maximum(state.drone_position[..., 2] - state.deck_position[..., 2] - LEG_LENGTH, 0.0)
    speed = norm3(xp, state.drone_velocity - state.deck_point_velocity)
    if touchdown is not None:
        speed = xp.where(touchdown.contact != 0, xp.abs(touchdown.relative_vertical_speed), speed)
    offset = tag_offset(state) if offset is None else offset
    return -(weights.distance * offset + weights.height * height + weights.speed * speed)


def miss(
    state: TaskState,
    touchdown: TouchdownState,
    thresholds: ThresholdsLike,
    success_radius: float,
    offset: Any = None,
) -> Any:
    """How far a touchdown missed the success limits: the largest of speed, tilt and tag offset
    each over its limit (< 1: within all); inf without a touchdown on the deck's top surface.
    ``offset``: :func:`~ihrcf_env.tasks.outcome.tag_offset` of ``state`` if already computed."""
    xp = namespace(state.drone_position, touchdown.contact)
    ratio = xp.maximum(
        xp.maximum(
            xp.abs(touchdown.relative_vertical_speed) / thresholds.success_speed,
            touchdown.relative_tilt / thresholds.success_tilt,
        ),
        (tag_offset(state) if offset is None else offset) / success_radius,
    )
    on_top = xp.logical_and(touchdown.contact == CONTACT_DECK, touchdown.on_deck)
    return xp.where(on_top, ratio, xp.inf)


def failure_penalty(miss_ratio: Any, weights: LandingWeightsLike) -> Any:
    """The penalty (> 0) of a failed episode: ``near_miss + (crash - near_miss) * min(1, max(0,
    miss - 1))``, so a touchdown just outside the limits costs ``near_miss``, twice the limits or
    worse (or no touchdown on the deck: ``miss`` = inf) the full ``crash``."""
    xp = namespace(miss_ratio)
    grade = xp.minimum(1.0, xp.maximum(0.0, miss_ratio - 1.0))
    return weights.near_miss + (weights.crash - weights.near_miss) * grade


def landing_reward(
    state: TaskState,
    action: Any,
    outcome: Any,
    touchdown: TouchdownState,
    previous_potential: Any,
    weights: LandingWeightsLike,
    thresholds: ThresholdsLike,
    success_radius: float,
    control_dt: float,
    offset: Any = None,
) -> tuple[LandingRewardTerms, Any]:
    """The landing tasks' reward terms of a step and the new potential (the next step's
    ``previous_potential``): ``progress = Phi(s') - Phi(s)`` (:func:`landing_potential`, with the
    touchdown's approach speed once the episode ends), ``time = -time dt``, ``action = -action
    |a|^2 dt`` (``dt = control_dt``, s) and ``terminal = +success`` on a success,
    ``-failure_penalty(miss)`` on a crash, else 0. ``offset``:
    :func:`~ihrcf_env.tasks.outcome.tag_offset` of ``state`` if already computed."""
    xp = namespace(state.drone_position, action)
    offset = tag_offset(state) if offset is None else offset
    ended = (outcome != 0) & (touchdown.contact != 0)
    landed = TouchdownState(xp.where(ended, touchdown.contact, 0), *touchdown[1:])
    phi = landing_potential(state, weights, landed, offset)
    penalty = failure_penalty(miss(state, touchdown, thresholds, success_radius, offset), weights)
    terminal = xp.where(outcome == SUCCESS, weights.success, xp.where(is_crash(outcome), -penalty, 0.0))
    terms = LandingRewardTerms(
        progress=phi - previous_potential,
        time=xp.full_like(phi, -weights.time * control_dt),
        action=-weights.action * action_cost(action) * control_dt,
        terminal=terminal,
    )
    return terms, phi
