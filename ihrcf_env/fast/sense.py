"""The landing step's sensor readings of one env (the built-in sensors): the ToF array (the cone
model or one ideal ray per sensor, with the dead-sensor fault), the IMU and the projected camera's
frame (detector model, frame dropout). Draws are inputs (:class:`~ihrcf_env.fast.state.ReadDraws`)."""

from __future__ import annotations

import jax.numpy as jnp
from jax import Array

from ihrcf_env.fast.detector import STATUS_NAMES
from ihrcf_env.fast.episode import Episode
from ihrcf_env.fast.frames import dropout_step
from ihrcf_env.fast.params import StepParams
from ihrcf_env.fast.rays import true_ranges
from ihrcf_env.fast.tag_camera import Imaging, tag_read
from ihrcf_env.fast.tof import cone_ranges, read_cone, read_ideal

__all__ = ["STATUS_FRAME_LOST", "camera_frame", "tof_reading"]

#: Status of a frame lost to the dropout fault.
STATUS_FRAME_LOST = STATUS_NAMES.index("camera frame lost")


def tof_reading(
    p: StepParams,
    ep: Episode,
    position: Array,
    rotation: Array,
    deck_position: Array,
    deck_rotation: Array,
    time: Array,
    z: Array,
    u: Array,
) -> tuple[Array, Array]:
    """(ranges (4,) m, valid (4,)) of the ToF array at ``time`` (s) for the drone's and deck's
    poses, with the sample's normals ``z`` (4,) and uniforms ``u`` (4,)."""
    t = p.tof
    if t.model is not None:
        assert t.rays is not None
        mean, signal = cone_ranges(
            position, rotation, deck_position, deck_rotation, t.rays, t.max_range, p.scene, t.model
        )
        ranges, valid = read_cone(mean, signal, ep.tof_offset, z, u, t.model, t.max_range)
    else:
        r, hit = true_ranges(
            position, rotation, deck_position, deck_rotation, jnp.asarray(t.starts),
            jnp.asarray(t.directions), t.max_range, p.scene,
        )  # fmt: skip
        ranges, valid = read_ideal(r, hit, t.max_range)
    if t.dead is not None:
        dead = ep.dead & (time >= ep.dead_start)
        ranges = jnp.where(dead, t.max_range, ranges)
        valid = valid & ~dead
    return ranges, valid


def camera_frame(
    p: StepParams,
    ep: Episode,
    position: Array,
    rotation: Array,
    velocity: Array,
    angular_velocity: Array,
    deck_position: Array,
    deck_rotation: Array,
    normals: Array,
    uniform: Array,
    drop_u: Array,
    bad: Array,
    started: Array,
) -> tuple[Array, Array, Array, Array]:
    """One camera frame: (corners (4, 2) px, status, the dropout chain's ``bad`` and ``started``)."""
    c = p.camera
    assert c is not None
    im = ep.imaging
    imaging = (
        Imaging(
            im.light, im.ambient, im.diffuse, im.brightness, im.exposure, im.gain, velocity, angular_velocity
        )
        if c.realistic
        else None
    )
    r = tag_read(
        c.setup, position, rotation, deck_position, deck_rotation, normals, uniform, ep.field_omega,
        ep.field_phase, imaging,
    )  # fmt: skip
    corners, status = r.corners, r.status
    if c.dropout is not None:
        bad, started = dropout_step(bad, started, drop_u, c.dropout)
        status = jnp.where(bad, STATUS_FRAME_LOST, status)
        corners = jnp.where(bad, 0.0, corners)
    return corners, status.astype(jnp.int32), bad, started
