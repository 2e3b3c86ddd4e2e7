"""Range beams (ihrcf_env.fast.rays) against the closed-form numpy casts of the simulator
(ihrcf_env.sim.sensors.rays / ranging), float64."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.fast.rays import Scene, cast_rays, true_ranges
from ihrcf_env.sim.sensors.ranging import ClosedFormToF
from ihrcf_env.sim.sensors.rays import RayScene
from ihrcf_env.sim.sensors.rays import cast_rays as np_cast_rays

from .fast_helpers import Counted, rel_err, rotations

CFG = WorldConfig(camera=None)
RAY_SCENE = RayScene.of(CFG.deck.size, CFG.deck.thickness, CFG.stewart.base_radius, CFG.stewart.base_height)
SCENE = Scene(
    jnp.asarray(RAY_SCENE.deck_half_extents),
    jnp.asarray(RAY_SCENE.base_radius),
    jnp.asarray(RAY_SCENE.base_height),
)
MAX_RANGE = 4.0
TOF = ClosedFormToF(SensorRig().sensor_positions_body, MAX_RANGE, RAY_SCENE, None)
S_B, D_B, F_SELF, N_SELF = TOF._axis

CAST = Counted(lambda s, d, dp, dR: cast_rays(s, d, 2.5, dp, dR, SCENE))
RANGES = Counted(
    lambda p, R, dp, dR: true_ranges(p, R, dp, dR, S_B, D_B, MAX_RANGE, SCENE, jnp.asarray(F_SELF), N_SELF)
)


def decks(rng: np.random.Generator, n: int):
    dR = rotations(rng, n, 0.3)
    dp = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0.6, 1.1, n)])
    return dp, dR


def rays(rng: np.random.Generator, n: int, r: int, dp: np.ndarray):
    """Rays from around the deck in all directions, plus grazing and axis-parallel ones."""
    s = dp[:, None, :] + rng.uniform(-1.0, 1.0, (n, r, 3))
    s[..., 2] = np.abs(s[..., 2]) + 0.01
    d = rng.normal(size=(n, r, 3))
    d[:, 0] = [0.0, 0.0, -1.0]  # straight down (vertical: through the base's axis test)
    d[:, 1] = [1.0, 0.0, 0.0]  # horizontal, axis-parallel
    d[:, 2] = [1.0, 1.0, 1e-12]  # grazing the ground
    s[:, 3] = [0.0, 0.0, 0.0]  # starting on the ground, pointing along it
    d[:, 3] = [0.0, 1.0, 0.0]
    s[:, 4] = [0.0, 0.0, 0.1]  # starting inside the base
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    return s, d


def test_cast_rays_matches_numpy() -> None:
    rng = np.random.default_rng(0)
    dp, dR = decks(rng, 128)
    s, d = rays(rng, 128, 24, dp)
    # grazing the deck's top face along its x axis from outside, 1 um above it (a miss) and 1 um
    # below it (enters the side face); exactly in its plane rounding decides, as in any float cast
    s[:, 5] = dp + 0.8 * dR[:, :, 0] + 1e-6 * dR[:, :, 2]
    s[:, 6] = dp + 0.8 * dR[:, :, 0] - 1e-6 * dR[:, :, 2]
    d[:, 5] = d[:, 6] = -dR[:, :, 0]
    want = np_cast_rays(s, d, 2.5, dp, dR, RAY_SCENE)
    got = CAST(s, d, dp, dR)
    assert np.array_equal(np.asarray(got.hit), want.hit)
    assert (~want.hit[:, 5]).all() and want.hit[:, 6].all()
    assert want.hit.mean() > 0.3 and (~want.hit).mean() > 0.05
    assert rel_err(got.fraction, want.fraction) < 1e-12
    assert rel_err(got.normal, want.normal) < 1e-12


def test_true_ranges_match_closed_form_tof() -> None:
    rng = np.random.default_rng(1)
    n = 256
    dp, dR = decks(rng, n)
    R = rotations(rng, n, 0.6)
    p = dp + np.column_stack([rng.uniform(-0.8, 0.8, (n, 2)), rng.uniform(0.05, 3.0, n)])
    p[:8, 2] = dp[:8, 2] + 5.0  # beyond the range: misses read max_range
    p[8:16, :2] = dp[8:16, :2] + 0.7  # beams off the deck's edge: they see the ground or the base
    want_r, want_hit = TOF.true_ranges(p, R, dp, dR)
    got_r, got_hit = RANGES(p, R, dp, dR)
    assert np.array_equal(np.asarray(got_hit), want_hit)
    assert rel_err(got_r, want_r) < 1e-12
    assert (~want_hit).any() and want_hit.any()
    assert np.all(np.asarray(got_r)[:8] <= MAX_RANGE)


def test_jit_vmap_compiles_once() -> None:
    rng = np.random.default_rng(2)
    before = RANGES.traces
    for _ in range(3):
        dp, dR = decks(rng, 32)
        RANGES(dp + [0.0, 0.0, 1.0], rotations(rng, 32), dp, dR)
    assert RANGES.traces - before <= 1
    # grad-free, but differentiable code paths must not produce NaN for on-axis rays
    assert jax.numpy.isfinite(RANGES(dp + [0.0, 0.0, 1.0], np.tile(np.eye(3), (32, 1, 1)), dp, dR)[0]).all()
