"""The small-matrix wrappers equal numpy.linalg to rounding (different algorithms, so not bitwise)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ihrcf_env.core.linalg import mahalanobis2, spd_inverse, svd


def _spd(rng: np.random.Generator, n: int, k: int) -> np.ndarray:
    A = rng.normal(size=(n, k, k))
    return A @ A.transpose(0, 2, 1) + 0.1 * np.eye(k)


@pytest.mark.parametrize("shape", [(3, 3), (4, 3), (8, 3), (4, 2)])
def test_svd_matches_numpy(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(0)
    for _ in range(200):
        a = rng.normal(size=shape) * 10.0 ** rng.uniform(-4, 4)
        u, s, vt = svd(a)
        assert u.shape == shape and s.shape == (shape[1],) and vt.shape == (shape[1], shape[1])
        s_np = np.linalg.svd(a, compute_uv=False)
        np.testing.assert_allclose(s, s_np, rtol=1e-12, atol=1e-13 * s_np[0])
        np.testing.assert_allclose(u @ np.diag(s) @ vt, a, rtol=0, atol=1e-12 * s_np[0])
        np.testing.assert_allclose(vt @ vt.T, np.eye(shape[1]), atol=1e-12)


def test_svd_rank_deficient_gives_orthonormal_factors() -> None:
    a = np.diag([2.0, 1.0, 0.0])  # a coplanar Kabsch cross-covariance
    u, s, vt = svd(a)
    np.testing.assert_allclose(s, [2.0, 1.0, 0.0])
    np.testing.assert_allclose(u.T @ u, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(vt @ vt.T, np.eye(3), atol=1e-15)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_spd_inverse_matches_numpy(k: int) -> None:
    rng = np.random.default_rng(k)
    for _ in range(200):
        S = _spd(rng, 3, k) * 10.0 ** rng.uniform(-8, 2)
        out = spd_inverse(S)
        assert out is not None
        inv, logdet = out
        np.testing.assert_allclose(inv, np.linalg.inv(S), rtol=1e-9)
        np.testing.assert_allclose(logdet, np.linalg.slogdet(S)[1], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_mahalanobis2_matches_numpy(k: int) -> None:
    rng = np.random.default_rng(10 + k)
    for _ in range(200):
        S = _spd(rng, 1, k)[0] * 10.0 ** rng.uniform(-8, 2)
        v = rng.normal(size=k) * math.sqrt(S[0, 0])
        assert mahalanobis2(S, v) == pytest.approx(float(v @ np.linalg.solve(S, v)), rel=1e-9)


def test_not_positive_definite_or_not_finite() -> None:
    not_pd = [
        np.diag([1.0, -1.0, 1.0]),
        np.diag([-1.0, -1.0, 1.0]),
        np.diag([1.0, -1.0, -1.0]),
        np.zeros((3, 3)),
    ]
    not_finite = [np.diag([1.0, np.nan, 1.0]), np.diag([1.0, np.inf, 1.0])]
    for S in not_pd + not_finite:
        assert mahalanobis2(S, np.ones(3)) == math.inf
    # spd_inverse checks the determinant only (documented): its callers add a positive-definite noise
    for S in [np.diag([1.0, -1.0, 1.0]), np.zeros((3, 3)), *not_finite]:
        assert spd_inverse(np.stack([np.eye(3), S])) is None
    assert mahalanobis2(np.eye(3), np.array([1.0, np.nan, 0.0])) == math.inf
    for k in (1, 2, 4):
        assert mahalanobis2(-np.eye(k), np.ones(k)) == math.inf
        assert mahalanobis2(np.eye(k), np.full(k, np.inf)) == math.inf
