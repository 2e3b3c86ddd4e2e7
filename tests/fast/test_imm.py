"""The IMM bank (ihrcf_env.fast.imm) against core.batch.imm.BatchImm, float64: a sequence of
predictions (with and without an input), gated 3-value and 1-value updates and scalar updates
along a direction, for positions and for angles (wrapped near +-pi)."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from fast_helpers import rel_err

from ihrcf_env.core.batch.imm import BatchImm
from ihrcf_env.fast import imm

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
        st = imm.imm_start(cfg)
        st = imm.reseed(st, z3[0], R3, 0.3)
        oks, d2s = [], []
        for k in range(4):
            st = imm.predict(st, dts[k], cfg, u[k])
            st, ok, d2 = imm.update(st, z3[k + 1], 0, 3, R3, gate, cfg)
            oks.append(ok)
            d2s.append(d2)
            st, ok, d2 = imm.update(st, z1[k], 2, 3, R3[2:3, 2:3], gate, cfg)
            oks.append(ok)
            d2s.append(d2)
            st, ok, d2 = imm.update_along(st, zs[k], h, var, gate, cfg)
            oks.append(ok)
            d2s.append(d2)
        return st, (oks, d2s), imm.x(st, cfg), imm.value_sigma(st, cfg)

    return jax.jit(jax.vmap(seq))


RUN = {a: _run(a) for a in (False, True)}


@pytest.mark.parametrize("angles", [False, True])
def test_sequence_matches_batch_imm(angles: bool) -> None:
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

    ref = BatchImm(N, ARGS["sigmas"], ARGS["drifts"], ARGS["q_white"], ARGS["switch_time"], angles)
    i = np.arange(N)
    ref.start(i, np.zeros(N))
    ref.reseed(i, z3[:, 0], R3, 0.3)
    want_ok, want_d2 = [], []
    for k in range(4):
        ref.predict(i, dts[:, k], u[:, k])
        for ok, d2 in (
            ref.update(i, z3[:, k + 1], (0, 3), R3, gate),
            ref.update(i, z1[:, k], (2, 3), R3[:, 2:3, 2:3], gate),
            ref.update_along(i, zs[:, k], h, var, gate),
        ):
            want_ok.append(ok)
            want_d2.append(d2)
    got_ok = np.stack([np.asarray(o) for o in oks])
    assert np.array_equal(got_ok, np.stack(want_ok))
    assert 0.1 < got_ok.mean() < 0.95  # accepted and rejected measurements both
    g, w = np.stack([np.asarray(d) for d in d2s]), np.stack(want_d2)
    assert np.array_equal(np.isinf(g), np.isinf(w))
    fin = np.isfinite(w)
    assert rel_err(g[fin], w[fin]) < 1e-9
    assert rel_err(st.X, ref.X) < 1e-9
    assert rel_err(st.Ps, ref.Ps) < 1e-9
    assert rel_err(st.mu, ref.mu) < 1e-9
    assert rel_err(xc, ref.x(i)) < 1e-9
    assert rel_err(sig, ref.value_sigma(i)) < 1e-9
