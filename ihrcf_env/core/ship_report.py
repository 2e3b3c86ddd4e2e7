"""Measured properties of the ship deck motion per sea state: spectra against their targets, the
quiescent fraction and the smallest Froude scale a platform reproduces (pure numpy/scipy).

:func:`ship_table` prints the markdown table of ``docs/deck-motion.md``::

    python -c "from ihrcf_env.core.ship_report import ship_table; print(ship_table())"
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.signal import welch

from ihrcf_env.core.quiescence import QuiescenceThresholds, quiescent_fraction
from ihrcf_env.core.ship import LARGE_STEWART, ShipOptions, response_psd, ship_profile, stroke_margin
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.core.waves import SEA_STATES

#: Candidate Froude length scales, ascending, of :func:`smallest_fitting_scale`.
SCALES: tuple[float, ...] = (
    2.0,
    5.0,
    10.0,
    15.0,
    20.0,
    25.0,
    30.0,
    40.0,
    50.0,
    60.0,
    80.0,
    100.0,
    150.0,
    200.0,
)
#: The spectral band compared: frequencies where the target PSD is at least this fraction of its peak.
PEAK_BAND = 0.25


def deck_record(
    options: ShipOptions, seed: int, duration_s: float, fs_hz: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(t (N,), offset (N, 3), rpy (N, 3)) of the seeded deck motion, model scale."""
    profile = ship_profile(np.random.default_rng(seed), options)
    t = np.arange(0.0, duration_s, 1.0 / fs_hz)
    offset, rpy = profile.sample(t)
    return t, offset, rpy


def spectrum_ratios(
    options: ShipOptions, seed: int = 0, duration_s: float | None = None, fs_hz: float | None = None
) -> NDArray[np.float64]:
    """(6,) Welch band power / target band power of the deck's (x, y, z, roll, pitch, yaw) over
    the band where the target (:func:`~ihrcf_env.core.ship.response_psd`) is at least
    :data:`PEAK_BAND` of its peak. The record lasts 4 h full scale by default, sampled at 4 Hz
    full scale; Welch segments of 4096 samples (Hann, half overlap)."""
    ts = math.sqrt(options.length_scale)
    duration = duration_s if duration_s is not None else 4 * 3600.0 / ts
    fs = fs_hz if fs_hz is not None else 4.0 * ts
    t, offset, rpy = deck_record(options, seed, duration, fs)
    x = np.concatenate([offset, rpy], axis=1).T
    f, p = welch(x, fs=fs, nperseg=min(4096, t.shape[0]))
    target = response_psd(options, f)
    out = np.empty(6)
    for k in range(6):
        band = target[k] >= PEAK_BAND * target[k].max()
        out[k] = p[k][band].sum() / target[k][band].sum()
    return out


def smallest_fitting_scale(
    options: ShipOptions,
    geometry: StewartGeometry,
    horizon_s: float = 730.0,
    seeds: Sequence[int] = range(5),
    scales: Sequence[float] = SCALES,
) -> float | None:
    """The smallest length scale in ``scales`` at which the legs of ``geometry`` follow the deck
    motion of every seed in ``seeds`` over ``horizon_s`` model seconds (checked on the deck's
    20 Hz reset grid); None if none does. The default horizon covers a 600 s check after a random
    start of up to 130 s."""
    for lam in sorted(scales):
        opts = dataclasses.replace(options, length_scale=lam)
        if all(
            stroke_margin(ship_profile(np.random.default_rng(s), opts), geometry, horizon_s)[0] >= 0
            for s in seeds
        ):
            return lam
    return None


def ship_table(
    codes: Sequence[int] = (3, 4, 5, 6),
    seed: int = 0,
    fit_seeds: Sequence[int] = range(5),
    quick: bool = False,
) -> str:
    """Markdown table, one row per WMO sea-state preset with the default vessel, heading and
    speed: the deck's significant amplitudes (2 standard deviations, full scale), its peak
    encounter period, the spectrum check (:func:`spectrum_ratios`) of heave / roll / pitch, the
    quiescent fraction (default full-scale thresholds over a 1 h record) and the smallest length
    scale fitting the paper's platform and :data:`~ihrcf_env.core.ship.LARGE_STEWART`.
    ``quick`` skips the spectrum check and the scale search (dashes)."""
    rows = [
        "| WMO code | sea | Hs (m) | Tp (s) | deck heave (m) | roll (deg) | pitch (deg) | peak period (s) "
        "| PSD ratio heave / roll / pitch | quiescent | scale, paper platform | scale, large platform |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for code in codes:
        sea = SEA_STATES[code]
        full = ShipOptions(sea_state=code, length_scale=1.0)
        profile = ship_profile(np.random.default_rng(seed), full)
        sig = 2.0 * profile.deck_std()
        f = np.linspace(0.0, 1.0, 2001)
        heave_psd = response_psd(full, f)[2]
        peak_period = 1.0 / f[int(np.argmax(heave_psd))]
        t, offset, rpy = deck_record(full, seed, 3600.0, 10.0)
        quiet = quiescent_fraction(t, offset, rpy, QuiescenceThresholds())
        if quick:
            ratio = paper = large = "-"
        else:
            r = spectrum_ratios(full, seed)
            ratio = f"{r[2]:.2f} / {r[3]:.2f} / {r[4]:.2f}"
            paper = _scale(smallest_fitting_scale(full, StewartGeometry(), seeds=fit_seeds))
            large = _scale(smallest_fitting_scale(full, LARGE_STEWART, seeds=fit_seeds))
        rows.append(
            f"| {code} | {sea.name.replace('_', ' ')} | {sea.hs:.2f} | {sea.tp:.1f} | {sig[2]:.2f} | "
            f"{math.degrees(sig[3]):.2f} | {math.degrees(sig[4]):.2f} | {peak_period:.1f} | {ratio} | "
            f"{100 * quiet:.0f} % | {paper} | {large} |"
        )
    return "\n".join(rows) + "\n"


def _scale(lam: float | None) -> str:
    return "none listed" if lam is None else f"{lam:g}"


__all__ = [
    "PEAK_BAND",
    "SCALES",
    "deck_record",
    "ship_table",
    "smallest_fitting_scale",
    "spectrum_ratios",
]
