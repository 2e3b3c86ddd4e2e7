"""The autopilot's GNSS/INS navigation errors for one drone: the port of
:class:`ihrcf_env.sim.navigation.GNSSINSNavigation`. The position error is a first-order process
driven by an exponentially correlated velocity error, plus white velocity noise, advanced once per
physics step; the draws (standard normals) are inputs, so a caller decides their stream. World
frame, m and m/s.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np
from jax import Array

__all__ = ["NavConstants", "NavState", "nav_constants", "nav_estimate", "nav_start", "nav_step"]


class NavConstants(NamedTuple):
    """The error model over one physics step (host-side, :func:`nav_constants`)."""

    phi_v: float
    phi_p: float
    gain_p: float
    inv_tp: float
    q_v: tuple[float, float, float]
    w: float
    sp: tuple[float, float, float]
    sv: tuple[float, float, float]
    a: float
    b: float


class NavState(NamedTuple):
    """Position error ``ep`` (3,) m, correlated velocity error ``ev`` (3,) and white velocity noise
    ``white`` (3,) m/s."""

    ep: Array
    ev: Array
    white: Array


def nav_constants(errors: Any, dt: float) -> NavConstants:
    """The :class:`NavConstants` of a ``NavigationErrors``-like object and the physics step ``dt`` (s)."""
    tp, tv = float(errors.position_time_constant), float(errors.velocity_time_constant)
    phi_v, phi_p = math.exp(-dt / tv), math.exp(-dt / tp)
    sv = np.asarray(errors.velocity_sigma, dtype=np.float64)
    sp = np.asarray(errors.position_sigma, dtype=np.float64)
    return NavConstants(
        phi_v,
        phi_p,
        tp * (1.0 - phi_p),
        1.0 / tp,
        tuple((sv * math.sqrt(1.0 - phi_v**2)).tolist()),
        float(errors.velocity_noise),
        tuple(sp.tolist()),
        tuple(sv.tolist()),
        1.0 / tp,
        1.0 / tv,
    )


def nav_start(z: Array, c: NavConstants) -> NavState:
    """The stationary start of the draws ``z`` (3, 3) (velocity error, position error's own part,
    white noise)."""
    sv, sp = jnp.asarray(c.sv), jnp.asarray(c.sp)
    ev = sv * z[0]
    cov = sv**2 / (c.a + c.b)
    gain = jnp.where(sv > 0, cov / jnp.maximum(sv**2, 1e-300), 0.0)
    rest = jnp.sqrt(jnp.maximum(sp**2 - gain * cov, 0.0))
    return NavState(gain * ev + rest * z[1], ev, c.w * z[2])


def nav_step(st: NavState, z: Array, c: NavConstants) -> NavState:
    """One physics step of the errors with the draws ``z`` (6,)."""
    new = c.phi_v * st.ev + jnp.asarray(c.q_v) * z[:3]
    ep = c.phi_p * st.ep + c.gain_p * 0.5 * (st.ev + new)
    return NavState(ep, new, c.w * z[3:])


def nav_estimate(st: NavState, position: Array, velocity: Array, c: NavConstants) -> tuple[Array, Array]:
    """The autopilot's (position, velocity) estimate of the true state."""
    return position + st.ep, velocity + st.ev - st.ep * c.inv_tp + st.white
