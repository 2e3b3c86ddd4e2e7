"""The camera's frames between exposure and observation for one environment: the latency as a
fixed-size ring of frames in flight (the port of :class:`ihrcf_env.sim.sensors.timing.DelayLine`)
and the burst frame dropout (Gilbert's two-state chain of :class:`ihrcf_env.sim.faults.CameraDropout`,
one transition per frame, its uniform an input).

Times are physics ticks (integers, the exposure's tick); a frame exposed at tick ``t`` is shown from
the first read at a tick ``>= t + latency_ticks``; every read shows the newest frame due (the older
ones due with it are dropped). Frames are the tag-corner reading: corners (4, 2) px and the status
code (:data:`ihrcf_env.fast.detector.STATUS_NAMES`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
from jax import Array

__all__ = [
    "STATUS_NO_FRAME",
    "TICK_EPS",
    "FramePipe",
    "dropout_params",
    "dropout_step",
    "pipe_deliver",
    "pipe_init",
    "pipe_push",
    "pipe_size",
]

#: Status code of the reading before the first frame of an episode has arrived ("tag not detected").
STATUS_NO_FRAME = 1
#: Tolerance (physics ticks) of the delivery test: a frame due within it of a tick is due there.
TICK_EPS = 1e-6


class FramePipe(NamedTuple):
    """Frames in flight and the frame shown: ``corners`` (B, 4, 2) px, ``status`` (B,), ``exposed``
    (B,) tick (-1: an empty slot), ``slot`` the next slot written; ``held_corners`` (4, 2),
    ``held_status``, ``held_tick`` (the shown frame's exposure tick, -1: none yet)."""

    corners: Array
    status: Array
    exposed: Array
    slot: Array
    held_corners: Array
    held_status: Array
    held_tick: Array


def pipe_size(latency_ticks: float, period_ticks: int) -> int:
    """Slots a pipe needs for a latency of ``latency_ticks`` with a frame every ``period_ticks``
    (the most frames ever in flight at once, plus the one exposed at the read)."""
    if period_ticks < 1:
        raise ValueError(f"period_ticks must be >= 1, got {period_ticks!r}")
    return max(1, math.ceil((latency_ticks - TICK_EPS) / period_ticks) + 1)


def pipe_init(size: int, dtype: Any = jnp.float64) -> FramePipe:
    """An empty pipe of ``size`` slots (:func:`pipe_size`), no frame shown yet."""
    return FramePipe(
        jnp.zeros((size, 4, 2), dtype),
        jnp.zeros(size, jnp.int32),
        jnp.full(size, -1, jnp.int32),
        jnp.zeros((), jnp.int32),
        jnp.zeros((4, 2), dtype),
        jnp.full((), STATUS_NO_FRAME, jnp.int32),
        jnp.full((), -1, jnp.int32),
    )


def pipe_push(pipe: FramePipe, tick: Array, corners: Array, status: Array, expose: Array) -> FramePipe:
    """The pipe with the frame exposed at ``tick`` added when ``expose`` (unchanged otherwise)."""
    size = pipe.exposed.shape[0]
    i = pipe.slot
    put = jnp.arange(size) == i
    return pipe._replace(
        corners=jnp.where((put & expose)[:, None, None], corners[None], pipe.corners),
        status=jnp.where(put & expose, status, pipe.status),
        exposed=jnp.where(put & expose, tick, pipe.exposed),
        slot=jnp.where(expose, (i + 1) % size, i),
    )


def pipe_deliver(pipe: FramePipe, tick: Array, latency_ticks: float) -> FramePipe:
    """The pipe after a read at ``tick``: the frames due leave it, the newest of them is shown."""
    due = (pipe.exposed >= 0) & (tick - pipe.exposed >= latency_ticks - TICK_EPS)
    newest = jnp.argmax(jnp.where(due, pipe.exposed, -1))
    any_due = jnp.any(due)
    return pipe._replace(
        exposed=jnp.where(due, -1, pipe.exposed),
        held_corners=jnp.where(any_due, pipe.corners[newest], pipe.held_corners),
        held_status=jnp.where(any_due, pipe.status[newest], pipe.held_status),
        held_tick=jnp.where(any_due, pipe.exposed[newest], pipe.held_tick),
    )


def dropout_params(loss_rate: float, mean_burst: float) -> tuple[float, float, float]:
    """``(loss_rate, p_recover, p_fail)`` of the burst dropout (as ``CameraDropout`` derives them)."""
    p_fail = loss_rate / ((1.0 - loss_rate) * mean_burst) if loss_rate > 0 else 0.0
    return float(loss_rate), 1.0 / mean_burst, p_fail


def dropout_step(
    bad: Array, started: Array, u: Array, params: tuple[float, float, float]
) -> tuple[Array, Array]:
    """One frame of the burst dropout from its uniform ``u``: the chain's new state ``bad`` (the
    frame is lost) and ``started`` (the first frame draws the state from the stationary
    distribution)."""
    loss_rate, p_recover, p_fail = params
    new = jnp.where(started, jnp.where(bad, u >= p_recover, u < p_fail), u < loss_rate)
    return new, jnp.ones_like(started)
