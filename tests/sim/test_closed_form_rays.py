"""Closed-form ray casting (ihrcf_env.sim.sensors.rays / ranging) against PyBullet's rayTestBatch.

Bullet casts rays against convex shapes (the deck box, the base cylinder) with a GJK-based convex
cast that stops within a tolerance of the surface: its hit points lie up to EPS = 1 mm off the
exact surface (the largest offset measured over tens of thousands of rays is 0.9985 mm; the
ground plane, a triangle test, is exact). So a ray's Bullet hit fraction must lie between the
closed form's for the scene grown by EPS and shrunk by EPS (a hit on a nearer surface of the
grown scene is the earliest Bullet can report, the shrunk scene's the latest). Near an edge
(measured: up to about 9 mm) Bullet's normal blends the two faces' normals; more than EDGE = 10 mm
from an edge it is the face's (deck, ground), or within about a degree of it on the base's side
(its cylinder normal comes from GJK).
"""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.sensors import ToFConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.sim.sensors.ranging import ClosedFormToF
from ihrcf_env.sim.sensors.rays import RayScene, cast_rays, self_hits
from ihrcf_env.sim.sensors.tof import ToFArray
from ihrcf_env.sim.world import World

EPS = 1e-3  # m: Bullet's convex-cast tolerance (see the module docstring)
EDGE = 0.01  # m: hits farther than this from an edge have a face's normal in Bullet
NORMAL_DEG_FLAT = 1e-4  # deg: deck faces and ground, away from edges
NORMAL_DEG_BASE = 2.0  # deg: Bullet's cylinder side normals come from its GJK, not the surface
LENGTH = 4.0


@pytest.fixture(scope="module")
def world():
    w = World(WorldConfig(camera=None))
    yield w
    w.close()


def scene_of(w: World) -> RayScene:
    c = w.config
    return RayScene.of(c.deck.size, c.deck.thickness, c.stewart.base_radius, c.stewart.base_height)


def grown(scene: RayScene, e: float) -> RayScene:
    h = scene.deck_half_extents
    return RayScene((h[0] + e, h[1] + e, h[2] + e), scene.base_radius + e, scene.base_height + e)


def place_deck(w: World, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    q = Rotation.from_euler("xyz", rng.uniform(-0.3, 0.3, 3)).as_quat()
    R = matrix_from_quat(q)
    pos = np.array([*rng.uniform(-0.2, 0.2, 2), rng.uniform(0.6, 1.1)])
    half = w.config.deck.thickness / 2
    p.resetBasePositionAndOrientation(
        w.deck.body, (pos - R[:, 2] * half).tolist(), q.tolist(), physicsClientId=w.client
    )
    return w.deck.pose()


def edge_distance(points, deck_pos, deck_R, scene: RayScene):
    """Distance (m) of surface points to the nearest edge of the face they lie on (deck, base)."""
    half = np.asarray(scene.deck_half_extents)
    loc = (points - deck_pos) @ deck_R
    loc[:, 2] += half[2]
    deck = np.sort(np.abs(np.abs(loc) - half), axis=1)[:, 1]
    rho = np.hypot(points[:, 0], points[:, 1])
    z = points[:, 2]
    base = np.maximum(np.abs(rho - scene.base_radius), np.minimum(np.abs(z - scene.base_height), np.abs(z)))
    return np.minimum(deck, base)


def random_rays(kind: int, n: int, rng, deck_pos, deck_R, scene: RayScene):
    """Rays at the deck's edges (0), the base's rim (1), the deck top and the ground (2), anywhere
    (3); starts above the ground and at least 2 mm outside the plate and the base."""
    if kind == 0:
        e = rng.uniform(-0.45, 0.45, (n, 3))
        e[:, 2] = rng.uniform(-0.05, 0.01, n)
        side = rng.integers(0, 2, n)
        e[np.arange(n), side] = np.sign(rng.standard_normal(n)) * (0.4 + rng.normal(0, 0.003, n))
        target = deck_pos + e @ deck_R.T
    elif kind == 1:
        a, r = rng.uniform(0, 2 * np.pi, n), scene.base_radius + rng.normal(0, 0.01, n)
        target = np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(-0.01, 0.09, n)])
    elif kind == 2:
        target = np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), rng.uniform(-0.1, 1.0, n)])
    else:
        target = rng.uniform(-2, 2, (n, 3)) + [0, 0, 1]
    starts = target + rng.uniform(-1.5, 1.5, (n, 3)) + [0, 0, 1.2]
    loc = (starts - deck_pos) @ deck_R
    loc[:, 2] += scene.deck_half_extents[2]
    m = 2e-3
    in_deck = np.all(np.abs(loc) <= np.asarray(scene.deck_half_extents) + m, axis=1)
    in_base = (np.hypot(starts[:, 0], starts[:, 1]) <= scene.base_radius + m) & (
        starts[:, 2] <= scene.base_height + m
    )
    keep = ~in_deck & ~in_base & (starts[:, 2] > m)
    d = target[keep] - starts[keep]
    return starts[keep], d / np.linalg.norm(d, axis=1, keepdims=True)


def test_rays_match_pybullet(world):
    """Thousands of rays at the deck's edges, the base, the deck top and the ground."""
    w, scene = world, scene_of(world)
    p.resetBasePositionAndOrientation(w.quad.body, [50, 50, 50], [0, 0, 0, 1], physicsClientId=w.client)
    rng = np.random.default_rng(7)
    worst_perp = worst_deck = worst_base = 0.0
    for trial in range(16):
        dp, dR = place_deck(w, rng)
        starts, dirs = random_rays(trial % 4, 1500, rng, dp, dR, scene)
        hits = p.rayTestBatch(starts.tolist(), (starts + dirs * LENGTH).tolist(), physicsClientId=w.client)
        fb = np.array([h[2] for h in hits])
        nb = np.array([h[4] for h in hits])
        c = cast_rays(starts[None], dirs[None], LENGTH, dp[None], dR[None], scene)
        g = cast_rays(
            starts[None], dirs[None], LENGTH, (dp + EPS * dR[:, 2])[None], dR[None], grown(scene, EPS)
        )
        s = cast_rays(
            starts[None], dirs[None], LENGTH, (dp - EPS * dR[:, 2])[None], dR[None], grown(scene, -EPS)
        )
        assert np.all(fb >= g.fraction[0] - 1e-9) and np.all(fb <= s.fraction[0] + 1e-9)
        # rays whose hit is unambiguous: same body hit in both bracketing scenes, away from edges
        f, n = c.fraction[0], c.normal[0]
        cos_i = np.abs(np.sum(n * dirs, axis=1))
        clean = c.hit[0] & (np.abs(s.fraction[0] - g.fraction[0]) * LENGTH * cos_i <= 2.5 * EPS)
        clean &= edge_distance(starts + dirs * (f * LENGTH)[:, None], dp, dR, scene) > EDGE
        clean &= edge_distance(np.array([h[3] for h in hits]), dp, dR, scene) > EDGE
        assert clean.sum() > 500
        assert np.array_equal(np.array([h[0] for h in hits])[clean] >= 0, c.hit[0][clean])
        perp = np.abs(fb - f)[clean] * LENGTH * cos_i[clean]
        deg = np.degrees(np.arccos(np.clip(np.sum(nb * n, axis=1), -1, 1)))
        on_base = np.array([h[0] == w.deck.base_body for h in hits])
        worst_perp = max(worst_perp, perp.max())
        worst_deck = max(worst_deck, deg[clean & ~on_base].max())
        worst_base = max(worst_base, deg[clean & on_base].max())
    print(
        f"max |d| cos(i) {worst_perp:.3g} m, normal: deck/ground {worst_deck:.3g} deg, "
        f"base {worst_base:.3g} deg"
    )
    assert worst_perp <= EPS
    assert worst_deck <= NORMAL_DEG_FLAT
    assert worst_base <= NORMAL_DEG_BASE


def test_rows_independent_and_misses():
    scene = RayScene.of(0.8, 0.04, 0.55, 0.08)
    rng = np.random.default_rng(3)
    n = 9
    starts = rng.uniform(-1, 1, (n, 20, 3)) + [0, 0, 1.5]
    dirs = rng.standard_normal((n, 20, 3))
    dirs /= np.linalg.norm(dirs, axis=-1, keepdims=True)
    dpos = np.column_stack([rng.uniform(-0.1, 0.1, (n, 2)), np.full(n, 0.85)])
    dR = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n, 3))).as_matrix()
    full = cast_rays(starts, dirs, LENGTH, dpos, dR, scene)
    for i in range(n):
        one = cast_rays(starts[i : i + 1], dirs[i : i + 1], LENGTH, dpos[i : i + 1], dR[i : i + 1], scene)
        assert np.array_equal(one.fraction[0], full.fraction[i]) and np.array_equal(
            one.normal[0], full.normal[i]
        )
    up = cast_rays(
        np.array([[[3.0, 3.0, 1.0]]]), np.array([[[0.0, 0.0, 1.0]]]), LENGTH, dpos[:1], dR[:1], scene
    )
    assert not up.hit[0, 0] and up.fraction[0, 0] == 1.0 and not up.normal.any()
    # a ray starting inside the plate reports the base below, not the plate (as Bullet)
    inside = cast_rays(
        np.array([[[0.0, 0.0, 0.83]]]),
        np.array([[[0.0, 0.0, -1.0]]]),
        1.0,
        np.array([[0, 0, 0.85]]),
        np.eye(3)[None],
        scene,
    )
    assert inside.hit[0, 0] and inside.fraction[0, 0] == pytest.approx(0.75)


def test_self_hits_of_the_default_rig_are_none_and_legs_are_seen():
    """The default sensors see none of their drone; a ray aimed at a landing leg hits it."""
    from ihrcf_env.core.rig import SensorRig

    pos = SensorRig().sensor_positions_body
    f, _ = self_hits(pos, np.tile([0.0, 0.0, -1.0], (4, 1)), LENGTH)
    assert np.all(np.isinf(f))
    f, nrm = self_hits(np.array([[0.12, 0.3, -0.05]]), np.array([[0.0, -1.0, 0.0]]), 1.0)
    assert f[0] == pytest.approx(0.3 - 0.126) and np.allclose(nrm[0], [0, 1, 0])


def random_drones(rng, n: int, deck_pos):
    pos = deck_pos + np.column_stack([rng.uniform(-0.55, 0.55, (n, 2)), rng.uniform(0.3, 2.0, n)])
    R = Rotation.from_euler("ZYX", np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-0.3, 0.3, (n, 2))]))
    return pos, R.as_matrix()


@pytest.mark.parametrize("noise", ["ideal", "realistic"])
def test_tof_closed_form_matches_pybullet(world, noise):
    """ToFArray(deck=...) equals ClosedFormToF's rows bit for bit, and PyBullet's ToFArray within
    Bullet's tolerance: every ray inside the EPS bracket; the readings of sensors whose rays all hit
    faces more than EDGE from an edge within 2 mm, their signals within 1 %."""
    w, scene = world, scene_of(world)
    cfg = ToFConfig(noise=noise)
    bullet = ToFArray(w.client, cfg, w.config.rig)
    closed = ToFArray(w.client, cfg, w.config.rig, deck=w.deck)
    pos_b = w.config.rig.sensor_positions_body
    tof = ClosedFormToF(pos_b, cfg.max_range, scene, cfg.model)
    lo, hi = (
        ClosedFormToF(pos_b, cfg.max_range, grown(scene, EPS), cfg.model),
        ClosedFormToF(pos_b, cfg.max_range, grown(scene, -EPS), cfg.model),
    )
    rng = np.random.default_rng(11)
    n_clean, worst = 0, 0.0
    for _ in range(6):
        dp, dR = place_deck(w, rng)
        pos, R = random_drones(rng, 40, dp)
        deck = (np.tile(dp, (40, 1)), np.tile(dR, (40, 1, 1)))
        up, down = (deck[0] + EPS * dR[:, 2], deck[1]), (deck[0] - EPS * dR[:, 2], deck[1])
        if noise == "ideal":
            batch, hit = tof.true_ranges(pos, R, *deck)
            r_lo, r_hi = lo.true_ranges(pos, R, *up)[0], hi.true_ranges(pos, R, *down)[0]
        else:
            batch, signal = tof.cone_ranges(pos, R, *deck)
            r_lo = np.nan_to_num(lo.cone_returns(pos, R, *up)[0], nan=cfg.max_range)
            r_hi = np.nan_to_num(hi.cone_returns(pos, R, *down)[0], nan=cfg.max_range)
            h, starts, dirs = tof.cone_hits(pos, R, *deck)
            points = starts + dirs * (h.fraction * cfg.max_range)[..., None]
            edge = edge_distance(points.reshape(-1, 3), dp, dR, scene).reshape(40, 4, -1)
            clean = np.all(edge > EDGE, axis=2) & np.all(np.abs(r_hi - r_lo) < 4 * EPS, axis=2)
        for i in range(40):
            p.resetBasePositionAndOrientation(
                w.quad.body,
                pos[i].tolist(),
                Rotation.from_matrix(R[i]).as_quat().tolist(),
                physicsClientId=w.client,
            )
            pw, Rw = w.drone_pose()
            if noise == "ideal":
                one = closed.true_ranges(pos[i], R[i])
                assert np.array_equal(one[0], batch[i]) and np.array_equal(one[1], hit[i])
                ref, _ = bullet.true_ranges(pw, Rw)
                assert np.all(ref >= r_lo[i] - 1e-9) and np.all(ref <= r_hi[i] + 1e-9)
                continue
            one = closed.cone_ranges(pos[i], R[i])
            assert np.array_equal(one[0], batch[i], equal_nan=True) and np.array_equal(one[1], signal[i])
            rays, _ = bullet.cone_returns(pw, Rw)
            rays = np.nan_to_num(rays, nan=cfg.max_range)
            assert np.all(rays >= r_lo[i] - 1e-9) and np.all(rays <= r_hi[i] + 1e-9)
            ref, ref_signal = bullet.cone_ranges(pw, Rw)
            c = clean[i]
            n_clean += c.sum()
            worst = max(worst, float(np.max(np.abs(ref[c] - batch[i][c]), initial=0.0)))
            assert np.allclose(ref[c], batch[i][c], rtol=0, atol=2e-3)
            assert np.allclose(ref_signal[c], signal[i][c], rtol=0.01, atol=0)
    print(f"{noise}: clean sensors {n_clean} of 960, max reading difference {worst:.3g} m")
    assert noise == "ideal" or n_clean > 300
