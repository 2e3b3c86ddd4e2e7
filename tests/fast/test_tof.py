"""ToF readings (ihrcf_env.fast.tof) against the simulator's ToFArray with closed-form rays (the
ideal and the VL53L1X cone model: offsets, noise and dropout from the same draws), float64."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.fast.rays import Scene, true_ranges
from ihrcf_env.fast.tof import cone_model, cone_ranges, cone_rays_of, read_cone, read_ideal
from ihrcf_env.sim.sensors.base import BodyState
from ihrcf_env.sim.sensors.tof import ToFArray, ToFConfig
from ihrcf_env.sim.world import World

from .fast_helpers import rel_err, rotations

N = 64


@pytest.fixture(scope="module")
def world():
    w = World(WorldConfig(camera=None))
    yield w
    w.close()


def poses(w: World, seed: int):
    rng = np.random.default_rng(seed)
    dp, dR = w.deck.pose()
    R = rotations(rng, N, 0.4)
    p = dp + np.column_stack([rng.uniform(-0.6, 0.6, (N, 2)), rng.uniform(0.05, 3.0, N)])
    return dp, dR, p, R


@pytest.mark.parametrize("noise", ["ideal", "realistic"])
def test_readings_match_tof_array(world: World, noise: str) -> None:
    cfg = ToFConfig(noise=noise)
    tof = ToFArray(world.client, cfg, world.config.rig, deck=world.deck)
    cf = tof.closed_form
    assert cf is not None
    scene = Scene(
        jnp.asarray(cf.scene.deck_half_extents),
        jnp.asarray(cf.scene.base_radius),
        jnp.asarray(cf.scene.base_height),
    )
    dp, dR, p, R = poses(world, 1 if noise == "ideal" else 2)
    mr = cfg.max_range
    if noise == "ideal":
        s_b, d_b, f_self, n_self = cf._axis

        def one(pp, RR, z, u, off):
            r, hit = true_ranges(pp, RR, dp, dR, s_b, d_b, mr, scene, jnp.asarray(f_self), n_self)
            return read_ideal(r, hit, mr)

    else:
        model = cone_model(cfg.model)
        rays = cone_rays_of(*cf._cone)

        def one(pp, RR, z, u, off):
            mean, signal = cone_ranges(pp, RR, dp, dR, rays, mr, scene, model)
            return read_cone(mean, signal, off, z, u, model, mr)

    want_r, want_v, zs, us, offs = [], [], [], [], []
    for i in range(N):
        rng = np.random.default_rng(100 + i)
        tof.reset(rng)
        state = BodyState(0.0, p[i], R[i], np.zeros(4), np.zeros(3), np.zeros(3), np.zeros(3))
        out = tof.read(state, 0.04, rng)
        want_r.append(out["ranges"])
        want_v.append(out["ranges_valid"])
        again = np.random.default_rng(100 + i)  # the same draws
        off = again.standard_normal(4) * cfg.model.offset_sigma if cfg.model is not None else np.zeros(4)
        zs.append(again.standard_normal(4))
        us.append(again.random(4))
        offs.append(off)
    r, v = jax.jit(jax.vmap(one))(p, R, np.array(zs), np.array(us), np.array(offs))
    assert np.array_equal(np.asarray(v).astype(np.int8), np.array(want_v))
    # the simulator's observation is float32
    assert rel_err(np.asarray(r).astype(np.float32), np.array(want_r)) == 0.0
    assert np.array(want_v).mean() > 0.5 and (np.array(want_v) == 0).any()


def test_cone_ranges_match_closed_form_tof_in_float64(world: World) -> None:
    cfg = ToFConfig(noise="realistic")
    tof = ToFArray(world.client, cfg, world.config.rig, deck=world.deck)
    cf = tof.closed_form
    assert cf is not None
    scene = Scene(
        jnp.asarray(cf.scene.deck_half_extents),
        jnp.asarray(cf.scene.base_radius),
        jnp.asarray(cf.scene.base_height),
    )
    dp, dR, p, R = poses(world, 3)
    model, rays = cone_model(cfg.model), cone_rays_of(*cf._cone)
    mean, signal = jax.jit(
        jax.vmap(lambda pp, RR: cone_ranges(pp, RR, dp, dR, rays, cfg.max_range, scene, model))
    )(p, R)
    want_mean, want_signal = cf.cone_ranges(p, R, np.tile(dp, (N, 1)), np.tile(dR, (N, 1, 1)))
    assert np.array_equal(np.isnan(np.asarray(mean)), np.isnan(want_mean))
    ok = ~np.isnan(want_mean)
    assert rel_err(np.asarray(mean)[ok], want_mean[ok]) < 1e-12
    assert rel_err(signal, want_signal) < 1e-12
