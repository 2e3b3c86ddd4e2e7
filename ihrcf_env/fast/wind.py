"""Wind on one drone: the mean wind, Dryden gusts (a first-order Gauss-Markov process per axis of
(along, across, up) the mean wind, sampled every ``sample_dt`` and linearly interpolated) and the
force the wind adds to the drone's still-air drag (PX4's drag model). The port of
:class:`ihrcf_env.sim.disturbances.Wind` (``reset``, ``velocity_at``, ``__call__``).

The random draws are inputs: the two uniforms of the mean wind (speed, direction) and the
standard normals of the gust process (its stationary start, then one per sample and axis), so a
caller decides their stream. World frame, SI units.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
from jax import Array, lax

__all__ = [
    "DragConstants",
    "WindConstants",
    "WindEpisode",
    "drag_force",
    "wind_constants",
    "wind_episode",
    "wind_force",
    "wind_velocity",
]

FT = 0.3048


class DragConstants(NamedTuple):
    """PX4's drag model: the quadratic prefix ``mass 0.5 rho / bcoef`` and the linear terms
    ``mass mcoef`` per axis (3,)."""

    q0: float
    lin: tuple[float, float, float]


class WindConstants(NamedTuple):
    """A wind configuration (host-side, :func:`wind_constants`)."""

    mean_speed_min: float
    mean_speed_max: float
    turbulence: float
    min_advection: float
    sample_dt: float
    s_h: float
    s_w: float
    l_h: float
    l_w: float
    drag: DragConstants


def wind_constants(params: Any) -> WindConstants:
    """The :class:`WindConstants` of a ``WindParams``-like object (its fields and ``drag``)."""
    h = max(float(params.height), 0.5) / FT
    k = 0.177 + 0.000823 * h
    d = params.drag
    return WindConstants(
        float(params.mean_speed_min),
        float(params.mean_speed_max),
        float(params.turbulence),
        float(params.min_advection),
        float(params.sample_dt),
        0.1 / k**0.4,
        0.1,
        h / k**1.2 * FT,
        h * FT,
        DragConstants(
            d.mass * 0.5 * d.rho / d.bcoef, (d.mass * d.mcoef_xy, d.mass * d.mcoef_xy, d.mass * d.mcoef_z)
        ),
    )


class WindEpisode(NamedTuple):
    """One episode's wind: ``mean`` (3,) m/s and the gust ``samples`` (S, 3) (world, m/s) at times
    ``k sample_dt``; ``gusty`` False when there are no gusts."""

    mean: Array
    samples: Array
    gusty: Array


def wind_episode(u_speed: Array, u_direction: Array, normals: Array, c: WindConstants) -> WindEpisode:
    """The wind of the draws: uniforms ``u_speed`` and ``u_direction`` on [0, 1), ``normals``
    (S, 3) standard normals (row 0: the stationary start, then one row per sample step); S - 1 gust
    samples come out (S must exceed the episode's duration over ``sample_dt`` by 2)."""
    speed = c.mean_speed_min + (c.mean_speed_max - c.mean_speed_min) * u_speed
    direction = 2.0 * math.pi * u_direction
    co, si = jnp.cos(direction), jnp.sin(direction)
    mean = jnp.stack([speed * co, speed * si, jnp.zeros_like(speed)])
    k = c.turbulence * speed
    sigma = jnp.stack([k * c.s_h, k * c.s_h, k * c.s_w])
    v_adv = jnp.maximum(speed, c.min_advection)
    tau = jnp.stack([c.l_h / v_adv, c.l_h / v_adv, c.l_w / v_adv])
    a = jnp.exp(-c.sample_dt / tau)
    q = sigma * jnp.sqrt(1.0 - a * a)
    x0 = sigma * normals[0]

    def step(x: Array, n: Array) -> tuple[Array, Array]:
        return a * x + n * q, x

    _, out = lax.scan(step, x0, normals[1:])
    rot = jnp.array([[co, -si, 0.0], [si, co, 0.0], [0.0, 0.0, 1.0]])
    samples = out @ rot.T
    gusty = (c.turbulence != 0) & (speed != 0)
    return WindEpisode(mean, samples, gusty)


def wind_velocity(t: Array, ep: WindEpisode, c: WindConstants) -> Array:
    """The wind (3,) m/s at time ``t`` s: the mean plus the interpolated gust (zero gusts when the
    episode has none)."""
    u = jnp.maximum(t, 0.0) / c.sample_dt
    k = jnp.floor(u).astype(jnp.int32)
    a, b = ep.samples[k], ep.samples[k + 1]
    gust = a + (u - k) * (b - a)
    return ep.mean + jnp.where(ep.gusty, gust, 0.0)


def drag_force(va: Array, d: DragConstants) -> Array:
    """PX4's drag force (3,) N of the velocity through the air ``va`` (3,) m/s."""
    q = d.q0 * jnp.sqrt(va[0] * va[0] + va[1] * va[1] + va[2] * va[2])
    return -(jnp.asarray(d.lin) + q) * va


def wind_force(velocity: Array, air: Array, d: DragConstants) -> Array:
    """The force (3,) N the wind ``air`` adds to the still-air drag of a drone at ``velocity``:
    ``drag(v - w) - drag(v)``, zero in calm air."""
    calm = jnp.all(air == 0.0)
    return jnp.where(calm, 0.0, drag_force(velocity - air, d) - drag_force(velocity, d))
