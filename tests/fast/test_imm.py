"""The IMM bank (ihrcf_env.fast.imm) against the single filter (ihrcf_env.core.estimators.imm.Imm),
one filter per row, float64: a sequence of predictions (with and without an input), gated 3-value
and 1-value updates and scalar updates along a direction, for positions and for angles (wrapped
near +-pi)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.core.estimators.imm import Imm
from ihrcf_env.fast import imm

from .fast_helpers import rel_err

N = 128
ARGS = dict(
    sigmas=(0.5, 0.4, 1.0),
    drifts=[np.full(3, 0.2), np.array([2.0, 2.0, 1.0])],
    q_white=np.array([0.1, 0.1, 0.05]),
    switch_time=2.0,
)


def _run(angles: bool):
    cfg = imm.imm_config(angles=angles, **ARGS)

    def seq(z3, z1, zs, h, var, R3, gate, dts, u):
        st = imm.reseed(imm.imm_start(cfg), z3[0], R3, 0.3)

        def frame(st, inp):  # one frame: predict, then three gated updates (under lax.scan)
            dt, uk, z3k, z1k, zsk = inp
            st = imm.predict(st, dt, cfg, uk)
            st, ok_a, d2_a = imm.update(st, z3k, 0, 3, R3, gate, cfg)
            st, ok_b, d2_b = imm.update(st, z1k, 2, 3, R3[2:3, 2:3], gate, cfg)
            st, ok_c, d2_c = imm.update_along(st, zsk, h, var, gate, cfg)
            return st, (jnp.stack([ok_a, ok_b, ok_c]), jnp.stack([d2_a, d2_b, d2_c]))

        st, (oks, d2s) = jax.lax.scan(frame, st, (dts, u, z3[1:], z1, zs))
        return st, (oks.reshape(-1), d2s.reshape(-1)), imm.x(st, cfg), imm.value_sigma(st, cfg)

    return jax.jit(jax.vmap(seq))


RUN = {a: _run(a) for a in (False, True)}


@pytest.mark.parametrize("angles", [False, True])
def test_sequence_matches_the_single_imm(angles: bool) -> None:
    rng = np.random.default_rng(int(angles))
    scale = 3.1 if angles else 1.0
    z3 = rng.uniform(-scale, scale, (N, 5, 3))
    z1 = rng.uniform(-scale, scale, (N, 4, 1))
    zs = rng.normal(0, 1, (N, 4))
    h = rng.normal(0, 1, (N, 3))
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    var = rng.uniform(0.01, 0.1, N)
    A = rng.normal(0, 0.2, (N, 3, 3))
    R3 = A @ A.transpose(0, 2, 1) + 0.01 * np.eye(3)
    gate = np.where(rng.random(N) < 0.5, 9.0, np.inf)  # half gated (some measurements rejected)
    dts = rng.uniform(0.02, 0.1, (N, 4))
    dts[:4, 1] = 0.0  # no time passes: predict leaves the bank
    u = rng.normal(0, 1, (N, 4, 3))
    u[::3, 2] = np.nan  # no input
    st, (oks, d2s), xc, sig = RUN[angles](z3, z1, zs, h, var, R3, gate, dts, u)

    want_ok, want_d2 = np.zeros((12, N), dtype=bool), np.zeros((12, N))
    refs = []
    for i in range(N):
        ref = Imm(ARGS["sigmas"], ARGS["drifts"], ARGS["q_white"], ARGS["switch_time"], 0.0, angles)
        ref.reseed(z3[i, 0], R3[i], 0.3)
        g = float(gate[i])
        for k in range(4):
            ref.predict(float(dts[i, k]), u[i, k] if np.isfinite(u[i, k]).all() else None)
            for j, (ok, d2) in enumerate(
                (
                    ref.update(z3[i, k + 1], (0, 3), R3[i], g),
                    ref.update(z1[i, k], (2, 3), R3[i, 2:3, 2:3], g),
                    ref.update_along(float(zs[i, k]), h[i], float(var[i]), g),
                )
            ):
                want_ok[3 * k + j, i], want_d2[3 * k + j, i] = ok, d2
        refs.append(ref)
    got_ok = np.asarray(oks).T  # (updates, N), in the order of the frames' updates
    assert np.array_equal(got_ok, want_ok)
    assert 0.1 < got_ok.mean() < 0.95  # accepted and rejected measurements both
    g, w = np.asarray(d2s).T, want_d2
    assert np.array_equal(np.isinf(g), np.isinf(w))
    fin = np.isfinite(w)
    assert rel_err(g[fin], w[fin]) < 1e-9
    assert rel_err(st.X, np.stack([r.X for r in refs])) < 1e-9
    assert rel_err(st.Ps, np.stack([r.Ps for r in refs])) < 1e-9
    assert rel_err(st.mu, np.stack([r.mu for r in refs])) < 1e-9
    assert rel_err(xc, np.stack([r.x for r in refs])) < 1e-9
    assert rel_err(sig, np.array([r.value_sigma() for r in refs])) < 1e-9


def test_stacked_banks_predict_as_each_bank() -> None:
    """``predict_banks`` over a position bank (with an input and value noise) and an angle bank
    (no input) is ``predict`` of each."""
    rng = np.random.default_rng(7)
    cfgs = (imm.imm_config(**ARGS), imm.imm_config(angles=True, q_value=np.diag([0.01, 0.01, 0.0]), **ARGS))
    n = 16

    def banks(z: np.ndarray, R: np.ndarray) -> imm.ImmState:
        return imm.reseed(imm.imm_start(cfgs[0]), z, R, 0.3)

    A = rng.normal(0, 0.2, (n, 2, 3, 3))
    R = A @ A.transpose(0, 1, 3, 2) + 0.01 * np.eye(3)
    z = rng.uniform(-3.1, 3.1, (n, 2, 3))
    dt = rng.uniform(0.02, 0.1, (n, 2))
    dt[:3, 1] = 0.0
    u = rng.normal(0, 1, (n, 3))
    q = rng.normal(0, 0.1, (n, 3, 3))
    q = q @ q.transpose(0, 2, 1)

    def run(z, R, dt, u, q):
        st = jax.vmap(banks)(z, R)
        nan = jnp.full(3, jnp.nan)
        both = imm.predict_banks(st, dt, cfgs, jnp.stack([u, nan]), jnp.stack([q, jnp.zeros((3, 3))]))
        pos = imm.predict(jax.tree_util.tree_map(lambda a: a[0], st), dt[0], cfgs[0], u, q)
        att = imm.predict(jax.tree_util.tree_map(lambda a: a[1], st), dt[1], cfgs[1])
        return both, pos, att

    both, pos, att = jax.jit(jax.vmap(run))(z, R, dt, u, q)
    for k, one in enumerate((pos, att)):
        for got, want in zip(both, one, strict=True):
            assert rel_err(np.asarray(got)[:, k], want) < 1e-12
