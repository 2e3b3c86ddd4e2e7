"""Fitting the detector model to rendered frames: :class:`DetectorSamples` (rendered frames paired
with their projected features), :func:`fit_quality` (one camera quality),
:func:`merge_samples` and :func:`fit_detector_params` (every quality; the corner error pooled).

The model is described in ``docs/detector_model.md``; the frames come from
``ihrcf-fit-detector`` (:mod:`ihrcf_env.experiments.detector_fit`). Pure numpy / scipy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.detector_model.features import N_BASIS, corner_basis, image_margin
from ihrcf_env.core.detector_model.params import COEFFICIENT_FIELDS, QualityParams


@dataclass(frozen=True, eq=False)
class DetectorSamples:
    """Rendered frames of one camera quality paired with their projected features, for
    :func:`fit_quality`. Frames of one track are consecutive control steps and consecutive in the
    arrays (the fit of the temporal correlation uses neighbours with the same ``track``).

    Attributes:
        corners, quiet_zone: (N, 4, 2) true projected corners of the tag and of its quiet zone, px.
        cos_view: (N,) viewing cosine. noise_ratio: (N, 4). blur_px: (N,).
        detected: (N, 4, 2) TagDetector's corners, NaN where it found nothing.
        track: (N,) int track id. width, height: image size (px).
    """

    corners: NDArray[np.float64]
    quiet_zone: NDArray[np.float64]
    cos_view: NDArray[np.float64]
    noise_ratio: NDArray[np.float64]
    blur_px: NDArray[np.float64]
    detected: NDArray[np.float64]
    track: NDArray[np.int64]
    width: int
    height: int

    def __post_init__(self) -> None:
        n = np.asarray(self.corners).shape[0]
        shapes = {
            "corners": (n, 4, 2),
            "quiet_zone": (n, 4, 2),
            "cos_view": (n,),
            "noise_ratio": (n, 4),
            "blur_px": (n,),
            "detected": (n, 4, 2),
            "track": (n,),
        }
        for name, shape in shapes.items():
            a = np.asarray(getattr(self, name), dtype=np.int64 if name == "track" else np.float64)
            if a.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
            object.__setattr__(self, name, a)

    @property
    def found(self) -> NDArray[np.bool_]:
        """(N,) frames where the detector found the tag."""
        out: NDArray[np.bool_] = np.logical_not(np.isnan(self.detected).any(axis=(1, 2)))
        return out


#: Detected corners further than this from the projection are not used to fit the noise (px).
OUTLIER_PX = 5.0
#: Frames up to this many steps apart within a track inform the fit of the correlation.
MAX_LAG = 5
#: The noise is fitted on frames whose corners' interior angles are within acos(+-0.5) = 60..120 deg
#: and whose shortest edge is at least 20 px: the operating range (the small-tag and oblique frames
#: only fit the detection limits; beyond the range the linear features extrapolate).
NOISE_FIT_MAX_COS_ANGLE = 0.5
NOISE_FIT_MIN_SIDE_PX = 20.0


def _noise_nll(
    theta: NDArray[np.float64],
    X: NDArray[np.float64],
    y: NDArray[np.float64],
    extra_n: NDArray[np.float64],
    extra_b: NDArray[np.float64],
    with_extra: bool,
) -> tuple[float, NDArray[np.float64]]:
    """Gaussian negative log-likelihood (and gradient) of the corner errors ``y`` (M, 2) along
    (radial, tangential) with features ``X`` (M, N_BASIS)."""
    p = N_BASIS
    total = 0.0
    grad = np.zeros_like(theta)
    cn, cb = (theta[4 * p], theta[4 * p + 1]) if with_extra else (0.0, 0.0)
    g_cn = g_cb = 0.0
    for k in range(2):
        beta = theta[2 * k * p : (2 * k + 1) * p]
        gamma = theta[(2 * k + 1) * p : (2 * k + 2) * p]
        mu = X @ beta
        base = np.exp(2.0 * (X @ gamma))
        s2 = base + cn * cn * extra_n + cb * cb * extra_b
        r = y[:, k] - mu
        total += float(np.sum(0.5 * np.log(s2) + 0.5 * r * r / s2))
        grad[2 * k * p : (2 * k + 1) * p] = -(r / s2) @ X
        w = 0.5 / s2 - 0.5 * r * r / (s2 * s2)
        grad[(2 * k + 1) * p : (2 * k + 2) * p] = (w * 2.0 * base) @ X
        g_cn += float(np.sum(w * 2.0 * cn * extra_n))
        g_cb += float(np.sum(w * 2.0 * cb * extra_b))
    if with_extra:
        grad[4 * p], grad[4 * p + 1] = g_cn, g_cb
    return total, grad


def _bernoulli_nll(detected: NDArray[np.bool_], p: NDArray[np.float64]) -> float:
    q = np.clip(p, 1e-9, 1.0 - 1e-9)
    return float(-np.sum(np.where(detected, np.log(q), np.log1p(-q))))


def _best_threshold(values: NDArray[np.float64], ok: NDArray[np.bool_], grid: NDArray[np.float64]) -> float:
    """The threshold ``c`` of the rule "detected iff value >= c" that agrees with ``ok`` most often
    (the middle of the best run of grid points)."""
    if values.size == 0:
        return float(grid[0])
    agree = np.array([np.sum((values >= c) == ok) for c in grid])
    best = np.flatnonzero(agree == agree.max())
    run = best[: np.argmax(np.diff(np.append(best, best[-1] + 2)) > 1) + 1]  # first run of maxima
    return float(grid[run[len(run) // 2]])


def fit_quality(samples: DetectorSamples, with_extra: bool) -> tuple[QualityParams, dict[str, Any]]:
    """Fit :class:`QualityParams` to rendered frames (see the module docstring for the model and
    :mod:`ihrcf_env.experiments.detector_fit` for the frames); ``with_extra`` fits the noise and blur gains
    (the realistic camera). Returns the parameters and a small report (counts and checks)."""
    from scipy.optimize import minimize

    s = samples
    radial, tangential, basis, side = corner_basis(s.corners)
    margin = image_margin(s.corners, s.width, s.height)
    qmargin = image_margin(s.quiet_zone, s.width, s.height)
    edges = s.corners[:, [1, 2, 3, 0]] - s.corners
    min_side = np.hypot(edges[..., 0], edges[..., 1]).min(axis=1)
    found = s.found
    err = np.where(found[:, None, None], s.detected - s.corners, 0.0)
    y = np.stack([(err * radial).sum(-1), (err * tangential).sum(-1)], axis=-1)  # (N, 4, 2)
    operating = (np.abs(basis[..., 6]).max(axis=1) <= NOISE_FIT_MAX_COS_ANGLE) & (
        min_side >= NOISE_FIT_MIN_SIDE_PX
    )
    use = found & operating & (np.abs(err).max(axis=(1, 2)) < OUTLIER_PX)
    report: dict[str, Any] = {
        "frames": int(len(found)),
        "detected": int(found.sum()),
        "noise_frames": int(use.sum()),
        "outliers": int((found & operating & ~use).sum()),
    }

    # 1. corner error: mean and log s.d. on the basis, plus the realistic camera's extra variance
    X = basis[use].reshape(-1, N_BASIS)
    Y = y[use].reshape(-1, 2)
    # the noise ratio in percent (gain ~ 0.1-1): a well-scaled problem for the optimiser
    extra_n = (100.0 * s.noise_ratio[use].reshape(-1)) ** 2 * (100.0 / side[use].reshape(-1))
    extra_b = np.repeat(s.blur_px[use], 4) ** 2
    p = N_BASIS
    theta0 = np.zeros(4 * p + 2)
    for k in range(2):
        theta0[2 * k * p] = float(Y[:, k].mean())
        theta0[(2 * k + 1) * p] = math.log(float(Y[:, k].std()) + 1e-6)
    theta0[4 * p :] = 0.01
    bounds = [(None, None)] * (4 * p) + [(0.0, None)] * 2
    res = minimize(
        _noise_nll,
        theta0 if with_extra else theta0[: 4 * p],
        args=(X, Y, extra_n, extra_b, with_extra),
        jac=True,
        method="L-BFGS-B",
        bounds=bounds if with_extra else None,
        options={"maxiter": 2000},
    )
    theta = np.asarray(res.x)
    coef = [tuple(float(v) for v in theta[i * p : (i + 1) * p]) for i in range(4)]
    noise_gain, blur_gain = (
        (100.0 * float(theta[4 * p]), float(theta[4 * p + 1])) if with_extra else (0.0, 0.0)
    )
    draft = QualityParams(coef[0], coef[1], coef[2], coef[3], noise_gain=noise_gain, blur_gain=blur_gain)
    mean, sd = draft.error_moments(basis, side, s.noise_ratio, s.blur_px[:, None])
    z = (y - mean) / sd  # (N, 4, 2), meaningful where `use`
    zu = z[use].reshape(-1, 2)
    report["noise_fit_converged"] = bool(res.success)
    report["normalised_sd"] = [float(v) for v in zu.std(axis=0)]
    report["normalised_kurtosis"] = [float(v) for v in (zu**4).mean(axis=0) / (zu**2).mean(axis=0) ** 2]
    report["raw_mean_xy_px"] = [float(v) for v in err[use].reshape(-1, 2).mean(axis=0)]
    report["raw_rms_px"] = float(np.sqrt((err[use] ** 2).mean()))

    # 2. correlation of the normalised error between frames of a track, against the corners' image
    # displacement between them (pairs up to MAX_LAG frames apart: a function of the displacement,
    # not a Markov chain of small steps)
    ii, jj = [], []
    for lag in range(1, MAX_LAG + 1):
        ok = use[:-lag] & use[lag:] & (s.track[:-lag] == s.track[lag:])
        i = np.flatnonzero(ok)
        ii.append(i)
        jj.append(i + lag)
    i0, i1 = np.concatenate(ii), np.concatenate(jj)
    d = np.hypot(*(s.corners[i1] - s.corners[i0]).transpose(2, 0, 1))  # (pairs, 4)
    dd = np.repeat(d[..., None], 2, axis=-1).ravel()
    a, b = z[i0].ravel(), z[i1].ravel()
    near_pairs = dd < 1.0  # beyond 1 px the correlation is ~0: only the near pairs inform the fit

    def corr_nll(v: NDArray[np.float64]) -> float:
        rho = v[0] * np.exp(-((dd[near_pairs] / v[1]) ** 2))
        q = 1.0 - rho * rho
        x, y = a[near_pairs], b[near_pairs]
        return float(np.sum(0.5 * np.log(q) + (x * x - 2.0 * rho * x * y + y * y) / (2.0 * q)))

    corr_max, corr_length = 0.0, 0.15
    if near_pairs.sum() >= 20:
        best = min(
            (
                minimize(corr_nll, [r0, l0], method="L-BFGS-B", bounds=[(0.0, 0.999), (0.02, 5.0)])
                for r0 in (0.5, 0.9)
                for l0 in (0.1, 0.5)
            ),
            key=lambda r: float(r.fun),
        )
        corr_max, corr_length = float(best.x[0]), float(best.x[1])
    report["pairs"] = int(i0.size)
    by_d = {}
    for lo, hi in ((0.0, 0.1), (0.1, 0.2), (0.2, 0.4), (0.4, 1e9)):
        m = (dd >= lo) & (dd < hi)
        if m.sum() >= 20:
            by_d[f"{lo}-{hi if hi < 1e9 else 'inf'} px"] = [
                int(m.sum()),
                float(np.corrcoef(a[m], b[m])[0, 1]),
            ]
    report["correlation_by_displacement"] = by_d

    # 3. detection rules
    cos = s.cos_view
    sane = (cos >= 0.3) & (min_side >= 20.0)
    near = sane & (qmargin < -3.0) & (margin > -5.0) & (margin < 10.0)
    min_margin = _best_threshold(margin[near], found[near], np.arange(-2.0, 4.0001, 0.05))
    inside = margin >= min_margin
    cand = inside & sane
    band_low = band_high = 0.0
    band_prob = 0.0
    best_nll = _bernoulli_nll(found[cand], np.full(cand.sum(), found[cand].mean() if cand.any() else 1.0))
    qm, ok = qmargin[cand], found[cand]
    for lo in np.arange(-4.0, 4.0001, 0.25):
        for hi in np.arange(lo + 0.5, lo + 12.0001, 0.25):
            m = (qm >= lo) & (qm < hi)
            if m.sum() < 5 or (~m).sum() < 5:
                continue
            p_in, p_out = ok[m].mean(), ok[~m].mean()
            nll = _bernoulli_nll(ok[m], np.full(m.sum(), p_in)) + _bernoulli_nll(
                ok[~m], np.full((~m).sum(), p_out)
            )
            if nll < best_nll - 2.0:  # a band must explain at least a few failures
                best_nll, band_low, band_high = nll, float(lo), float(hi)
                band_prob = float(max(0.0, (p_out - p_in) / max(p_out, 1e-9)))
    in_band = (qmargin >= band_low) & (qmargin < band_high)
    sz = inside & ~in_band & (cos >= 0.3)

    def size_nll(v: NDArray[np.float64]) -> float:
        x = np.clip((min_side[sz] - v[0]) / v[1], -50, 50)
        return _bernoulli_nll(found[sz], (1.0 - v[2]) / (1.0 + np.exp(-x)))

    size_fit = minimize(
        size_nll, [11.0, 1.5, 0.005], method="L-BFGS-B", bounds=[(0.0, 200.0), (0.2, 20.0), (0.0, 0.5)]
    )
    size50, size_width, miss = (float(v) for v in size_fit.x)
    ob = inside & ~in_band & (min_side >= size50 + 4.0 * size_width)
    min_cos = _best_threshold(cos[ob], found[ob], np.arange(0.0, 0.5001, 0.002))
    prm = QualityParams(
        coef[0],
        coef[1],
        coef[2],
        coef[3],
        noise_gain=noise_gain,
        blur_gain=blur_gain,
        corr_max=corr_max,
        corr_length_px=corr_length,
        min_margin_px=min_margin,
        band_low_px=band_low,
        band_high_px=band_high,
        band_fail_prob=band_prob,
        size50_px=size50,
        size_width_px=size_width,
        min_cos_view=min_cos,
        miss_prob=miss,
    )
    # agreement of the fitted detection rules with the renderer (expected detection probability)
    band_p, small_p, miss_p = prm.detection_probability(qmargin, min_side)
    p_det = np.where(inside & (cos >= min_cos), (1 - band_p) * (1 - small_p) * (1 - miss_p), 0.0)
    report["detection_rate_rendered"] = float(found.mean())
    report["detection_rate_model"] = float(p_det.mean())
    report["detection_rules_frames"] = {
        "margin": int(near.sum()),
        "band": int(cand.sum()),
        "size": int(sz.sum()),
        "oblique": int(ob.sum()),
    }
    return prm, report


def merge_samples(*samples: DetectorSamples) -> DetectorSamples:
    """One :class:`DetectorSamples` of several (same image size); track ids are kept apart."""
    if not samples:
        raise ValueError("merge_samples needs at least one DetectorSamples")
    w, h = samples[0].width, samples[0].height
    if any((s.width, s.height) != (w, h) for s in samples):
        raise ValueError("merge_samples: the samples must share one image size")
    offset, tracks = 0, []
    for s in samples:
        tracks.append(s.track + offset)
        offset += int(s.track.max(initial=-1)) + 1
    return DetectorSamples(
        corners=np.concatenate([s.corners for s in samples]),
        quiet_zone=np.concatenate([s.quiet_zone for s in samples]),
        cos_view=np.concatenate([s.cos_view for s in samples]),
        noise_ratio=np.concatenate([s.noise_ratio for s in samples]),
        blur_px=np.concatenate([s.blur_px for s in samples]),
        detected=np.concatenate([s.detected for s in samples]),
        track=np.concatenate(tracks),
        width=w,
        height=h,
    )


#: The parameters of the corner error (fitted on all qualities' frames together).
NOISE_FIELDS: tuple[str, ...] = (*COEFFICIENT_FIELDS, "noise_gain", "blur_gain", "corr_max", "corr_length_px")


def fit_detector_params(
    samples: Mapping[str, DetectorSamples],
) -> tuple[dict[str, QualityParams], dict[str, Any]]:
    """Fit every quality of ``samples`` (quality -> frames): the detection rules on each quality's
    own frames, the corner error (:data:`NOISE_FIELDS`) on all frames together (the renderer's
    aliasing is the same for both qualities; the realistic frames' noise ratio and blur carry the
    extra variance, zero on ideal frames). Returns the parameters and the reports (per quality,
    and ``"pooled"`` for the error fit)."""
    qualities = list(samples)
    if not qualities:
        raise ValueError("fit_detector_params needs the samples of at least one quality")
    pooled, pooled_report = fit_quality(merge_samples(*samples.values()), with_extra=True)
    shared = {name: getattr(pooled, name) for name in NOISE_FIELDS}
    params: dict[str, QualityParams] = {}
    reports: dict[str, Any] = {"pooled": pooled_report}
    for q in qualities:
        own, report = fit_quality(samples[q], with_extra=q != "ideal")
        params[q] = replace(own, **shared)
        reports[q] = report
    return params, reports


__all__ = [
    "MAX_LAG",
    "NOISE_FIELDS",
    "NOISE_FIT_MAX_COS_ANGLE",
    "NOISE_FIT_MIN_SIDE_PX",
    "OUTLIER_PX",
    "DetectorSamples",
    "fit_detector_params",
    "fit_quality",
    "merge_samples",
]
