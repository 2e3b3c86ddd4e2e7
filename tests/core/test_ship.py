"""Ship-like deck motion: wave spectra and presets, the vessel response, spectra against their
targets, the shared sea, Froude scaling, the platform fit and quiescent periods."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest
from scipy.signal import coherence

from ihrcf_env.core.profiles import PROFILE_NAMES, make_profile
from ihrcf_env.core.quiescence import (
    QuiescenceThresholds,
    energy_index,
    heave_energy_bound,
    quiescent_fraction,
    quiescent_mask,
    quiescent_periods,
)
from ihrcf_env.core.ship import (
    DEFAULT_LENGTH_SCALE,
    FRIGATE,
    LARGE_STEWART,
    ShipMotion,
    ShipOptions,
    fits,
    response_psd,
    ship_profile,
    stroke_margin,
    transfer,
)
from ihrcf_env.core.ship_report import deck_record, ship_table, spectrum_ratios
from ihrcf_env.core.stewart import StewartGeometry
from ihrcf_env.core.waves import (
    SEA_STATES,
    WMO_HS_BANDS,
    SeaState,
    jonswap,
    pierson_moskowitz,
    sea_state,
)

W = np.linspace(0.01, 12.0, 200_000)


def _ship(seed: int = 0, **options: object) -> ShipMotion:
    return ship_profile(np.random.default_rng(seed), ShipOptions(**options))  # type: ignore[arg-type]


# -- spectra and presets ---------------------------------------------------------------------------
@pytest.mark.parametrize(("gamma", "tol"), [(1.0, 0.002), (3.3, 0.02), (7.0, 0.03)])
def test_spectrum_gives_its_significant_wave_height_and_peak(gamma, tol):
    hs, tp = 2.5, 9.0
    s = jonswap(W, hs, tp, gamma)
    assert 4 * math.sqrt(np.trapezoid(s, W)) == pytest.approx(hs, rel=tol)
    assert W[np.argmax(s)] == pytest.approx(2 * math.pi / tp, rel=1e-3)


def test_pierson_moskowitz_is_jonswap_with_gamma_one_and_jonswap_is_peakier():
    np.testing.assert_allclose(pierson_moskowitz(W, 2.0, 8.0), jonswap(W, 2.0, 8.0, 1.0))
    assert jonswap(W, 2.0, 8.0, 3.3).max() > 1.5 * pierson_moskowitz(W, 2.0, 8.0).max()
    assert jonswap(np.array([0.0, -1.0]), 2.0, 8.0).tolist() == [0.0, 0.0]


def test_presets_lie_in_their_wmo_bands_and_are_found_by_code_and_name():
    for code, s in SEA_STATES.items():
        lo, hi = WMO_HS_BANDS[code]
        assert lo <= s.hs <= hi
        assert sea_state(code) is s and sea_state(s.name) is s
    assert sea_state({"hs": 2.0, "tp": 9.0}) == SeaState(2.0, 9.0, 3.3, "custom")


@pytest.mark.parametrize(
    ("spec", "error", "match"),
    [
        ("tsunami", ValueError, "sea_state must be one of"),
        (9, ValueError, "sea_state code"),
        (True, TypeError, "sea_state must be a WMO code"),
        (4.0, TypeError, "sea_state must be a WMO code"),
        ({"hs": 1e300, "tp": 9.0}, ValueError, "sea_state.hs"),
        ({"hs": -1.0, "tp": 9.0}, ValueError, "sea_state.hs"),
        ({"hs": 2.0, "tp": 1e-170}, ValueError, "sea_state.tp"),
        ({"hs": 2.0, "tp": float("nan")}, ValueError, "sea_state.tp"),
        ({"hs": 10.0, "tp": 4.0}, ValueError, "steepness"),
        ({"hs": 2.0, "tp": 9.0, "gamma": 0.5}, ValueError, "sea_state.gamma"),
        ({"hs": "2", "tp": 9.0}, TypeError, "sea_state.hs"),
        ({"height": 2.0}, ValueError, "no parameter 'height'"),
    ],
)
def test_bad_sea_states_are_refused(spec, error, match):
    with pytest.raises(error, match=match):
        sea_state(spec)


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"length_scale": 0.5}, "ship.length_scale"),
        ({"length_scale": 1e300}, "ship.length_scale"),
        ({"speed": -1.0}, "ship.speed"),
        ({"n_components": 4}, "ship.n_components"),
        ({"vessel": {"roll_damping": 0.0}}, "vessel.roll_damping"),
        ({"vessel": {"deck_position": (0.0, 0.0, 1e9)}}, "vessel.deck_position"),
        ({"sea_state": "hurricane"}, "sea_state"),
        ({"ripples": 1}, "no parameter 'ripples'"),
    ],
)
def test_bad_ship_options_are_refused_naming_the_option(options, match):
    with pytest.raises(ValueError, match=match):
        make_profile("ship", np.random.default_rng(0), ship=options)


# -- the vessel response -----------------------------------------------------------------------------
def test_response_limits_and_symmetries():
    w = np.array([0.02, 0.5, 1.0])
    _, head = transfer(w, FRIGATE, math.pi, 0.0)
    _, beam = transfer(w, FRIGATE, math.pi / 2, 0.0)
    assert abs(head[2, 0]) == pytest.approx(1.0, abs=1e-3)  # long waves: the ship rides them
    assert np.abs(head[3]).max() < 1e-12  # head seas do not roll the ship
    assert np.abs(beam[4]).max() < 1e-12  # beam seas do not pitch it
    assert abs(beam[3, 1]) > 0.3 * 0.5**2 / 9.81  # but roll it (near resonance, amplified)
    # waves of one ship length are averaged out: far less heave than long waves
    k_l = 2 * math.pi / FRIGATE.length
    _, short = transfer(np.array([math.sqrt(9.81 * k_l)]), FRIGATE, math.pi, 0.0)
    assert abs(short[2, 0]) < 0.2


def test_encounter_frequency_rises_in_head_seas_and_falls_in_following_seas():
    w = np.array([0.6])
    we_head, _ = transfer(w, FRIGATE, math.pi, 8.0)
    we_follow, _ = transfer(w, FRIGATE, 0.0, 8.0)
    k = 0.36 / 9.81
    assert we_head[0] == pytest.approx(0.6 + k * 8.0)
    assert we_follow[0] == pytest.approx(0.6 - k * 8.0)


# -- determinism, smoothness, scaling -------------------------------------------------------------
def test_deterministic_per_seed_and_different_across_seeds():
    t = np.linspace(0.0, 60.0, 1201)
    a, b, c = (_ship(s).sample(t) for s in (3, 3, 4))
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert np.abs(a[0] - c[0]).max() > 1e-3
    off, rpy = _ship(3)(12.5)
    assert off.shape == (3,) and rpy.shape == (3,)
    np.testing.assert_allclose(off, a[0][250], atol=1e-12)


def test_phasor_recurrence_matches_direct_evaluation_and_motion_is_smooth():
    p = _ship(1)
    t = 500.0 + np.arange(5000) / 240.0  # a uniform grid: the block recurrence
    fast = p.ship_motion(t)
    direct = (np.exp(1j * np.outer(t, p.omega_e)) @ p.amplitudes.T).real
    np.testing.assert_allclose(fast, direct, atol=1e-9)
    off, _ = p.sample(t)
    jerk = np.diff(off[:, 2], 3) * 240.0**3  # m/s^3, model scale: no jumps
    assert np.abs(jerk).max() < 50.0


def test_short_and_irregular_grids_match_direct_evaluation():
    p = _ship(5)
    rng = np.random.default_rng(0)
    for t in (np.arange(100) * 0.3, np.sort(rng.uniform(0.0, 900.0, 1000))):
        direct = (np.exp(1j * np.outer(t, p.omega_e)) @ p.amplitudes.T).real
        np.testing.assert_allclose(p.ship_motion(t), direct, atol=1e-12)


def test_a_chunk_of_physics_rate_motion_costs_little_cpu_with_a_blas_thread_pool():
    """The sums are not handed to a BLAS thread pool, whose threads spin (CPU time) far longer
    than the sums take: a 30 s chunk at 240 Hz costs milliseconds of the calling thread's CPU
    time (the calling thread waits on the pool's threads by spinning too)."""
    from threadpoolctl import threadpool_limits

    p = _ship(1)
    t = 300.0 + np.arange(7200) / 240.0 * p.time_scale
    with threadpool_limits(limits=2):
        p.ship_motion(t[:300])  # warm up
        c0 = time.thread_time()
        p.ship_motion(t)
        cpu = time.thread_time() - c0
    assert cpu < 0.1, f"{cpu:.3f} s of CPU for one chunk"


def test_froude_scaling_lengths_over_lambda_angles_kept_times_over_sqrt_lambda():
    lam = 36.0
    full = _ship(2, length_scale=1.0)
    model = _ship(2, length_scale=lam)
    t_model = np.linspace(0.0, 20.0, 101)
    off_m, rpy_m = model.sample(t_model)
    off_f, rpy_f = full.sample(t_model * math.sqrt(lam))
    np.testing.assert_allclose(off_m * lam, off_f, atol=1e-9)
    np.testing.assert_allclose(rpy_m, rpy_f, atol=1e-12)


# -- spectra against their targets, one shared sea -----------------------------------------------------
def test_target_spectrum_integrates_to_the_components_variance():
    opts = ShipOptions(sea_state=5)
    f = np.linspace(0.0, 5.0, 5001)
    var = response_psd(opts, f).sum(axis=1) * (f[1] - f[0])
    std = ship_profile(np.random.default_rng(0), opts).deck_std()
    np.testing.assert_allclose(np.sqrt(var), std, rtol=0.03)


#: Welch band power around the peak (target >= 25 % of its peak) / target band power.
SPECTRUM_TOLERANCE = 0.10


@pytest.mark.parametrize(
    "options",
    [
        {"sea_state": 4},
        {"sea_state": 6, "length_scale": 60.0},
        {"sea_state": 5, "wave_heading": math.radians(100.0), "speed": 3.0},
        {"sea_state": {"hs": 2.0, "tp": 8.0, "gamma": 1.0}, "wave_heading": math.radians(30.0)},
    ],
    ids=["ss4", "ss6", "ss5-beam", "pm-following"],
)
def test_welch_spectrum_matches_the_target_around_the_peak(options):
    ratios = spectrum_ratios(ShipOptions(**options), seed=7)
    np.testing.assert_allclose(ratios[2:5], 1.0, atol=SPECTRUM_TOLERANCE)  # heave, roll, pitch


def test_heave_roll_pitch_share_one_sea():
    opts = ShipOptions(sea_state=5, wave_heading=math.radians(120.0))
    t, off, rpy = deck_record(opts, 0, 1500.0, 10.0)
    _, off2, rpy2 = deck_record(opts, 1, 1500.0, 10.0)
    f, c_pitch = coherence(off[:, 2], rpy[:, 1], fs=10.0, nperseg=512)
    _, c_roll = coherence(off[:, 2], rpy[:, 0], fs=10.0, nperseg=512)
    _, c_other = coherence(off[:, 2], rpy2[:, 1], fs=10.0, nperseg=512)  # another sea: control
    target = response_psd(opts, f)[2]
    band = target >= 0.25 * target.max()
    assert np.median(c_pitch[band]) > 0.9
    assert np.median(c_roll[band]) > 0.9
    assert np.median(c_other[band]) < 0.3


# -- the platform --------------------------------------------------------------------------------------
def test_default_ship_fits_the_papers_platform_over_the_checked_horizon():
    assert DEFAULT_LENGTH_SCALE == ShipOptions().length_scale
    for seed in range(3):
        p = make_profile("ship", np.random.default_rng(seed))
        assert isinstance(p, ShipMotion)
        assert fits(p, StewartGeometry(), 730.0)


def test_rough_seas_at_a_large_scale_model_need_the_large_platform():
    p = _ship(0, sea_state=6, length_scale=25.0)
    margin, t, leg = stroke_margin(p, StewartGeometry(), 300.0)
    assert margin < 0 and 0 <= t <= 300.0 and 1 <= leg <= 6
    assert not fits(p, StewartGeometry(), 300.0)
    assert fits(_ship(0, sea_state=6, length_scale=40.0), LARGE_STEWART, 300.0)


# -- quiescent periods ---------------------------------------------------------------------------------
def test_quiescent_mask_needs_both_calm_heave_and_level_deck_for_the_minimum_duration():
    t = np.arange(0.0, 10.0, 0.01)
    z = np.where(t < 3.0, 0.0, 0.5 * np.sin(3.0 * (t - 3.0)))  # calm 3 s, then heaving
    off = np.column_stack([np.zeros_like(t), np.zeros_like(t), z])
    rpy = np.zeros((t.size, 3))
    rpy[(t > 6.0) & (t < 7.5), 0] = math.radians(3.0)  # tilted while heaving: no help
    th = QuiescenceThresholds()
    periods = quiescent_periods(t, off, rpy, th)
    assert len(periods) == 1 and periods[0][0] == 0.0 and periods[0][1] == pytest.approx(3.0, abs=0.02)
    short = dataclasses.replace(th, min_duration=3.5)
    assert not quiescent_mask(t, off, rpy, short).any()  # a 3 s window is not a 3.5 s one
    rpy[:, 1] = math.radians(2.0)  # tilted throughout: never quiescent
    assert quiescent_fraction(t, off, rpy, th) == 0.0
    with pytest.raises(ValueError, match="quiescence needs"):
        quiescent_mask(t, off[:-1], rpy, th)


def test_quiescence_occurs_in_moderate_seas_and_more_in_calmer_seas():
    th = QuiescenceThresholds().scaled(DEFAULT_LENGTH_SCALE)
    fractions = {}
    for code in (3, 4, 5):
        t, off, rpy = deck_record(ShipOptions(sea_state=code), 0, 600.0, 40.0)
        fractions[code] = quiescent_fraction(t, off, rpy, th)
    assert fractions[4] > 0.0
    assert fractions[3] > fractions[4] > fractions[5]


def test_quiescence_is_froude_consistent_and_energy_index_is_low_when_quiescent():
    lam = 25.0
    t_m, off_m, rpy_m = deck_record(ShipOptions(length_scale=lam), 3, 400.0, 40.0)
    t_f, off_f, rpy_f = deck_record(
        ShipOptions(length_scale=1.0), 3, 400.0 * math.sqrt(lam), 40.0 / math.sqrt(lam)
    )
    th = QuiescenceThresholds()
    q_model = quiescent_fraction(t_m, off_m, rpy_m, th.scaled(lam))
    assert q_model == pytest.approx(quiescent_fraction(t_f, off_f, rpy_f, th), abs=0.01)
    assert q_model > 0.0
    mask = quiescent_mask(t_m, off_m, rpy_m, th.scaled(lam))
    e = energy_index(t_m, off_m, rpy_m, th.scaled(lam))
    assert np.median(e[mask]) < 2.0 < np.median(e[~mask])


def test_heave_energy_bound_is_the_amplitude_of_a_sinusoidal_heave():
    t = np.linspace(0.0, 10.0, 501)
    z, vz = 0.7 * np.sin(1.3 * t + 0.2), 0.7 * 1.3 * np.cos(1.3 * t + 0.2)
    np.testing.assert_allclose(heave_energy_bound(z, vz, 1.3), 0.7, rtol=1e-12)
    assert heave_energy_bound(z, vz, 2.6).min() < 0.69  # the wrong frequency misjudges it
    with pytest.raises(ValueError, match="omega"):
        heave_energy_bound(z, vz, 0.0)


def test_bad_thresholds_are_refused():
    with pytest.raises(ValueError, match="quiescence.tilt"):
        QuiescenceThresholds(tilt=-1.0)
    with pytest.raises(TypeError, match="quiescence.vertical_speed"):
        QuiescenceThresholds(vertical_speed="fast")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="length_scale"):
        QuiescenceThresholds().scaled(0.0)


# -- registration and the table ---------------------------------------------------------------------
def test_ship_is_a_profile_name_next_to_the_others_and_the_table_has_a_row_per_preset():
    assert PROFILE_NAMES == ("paper", "sea_state", "static", "ship")
    md = ship_table(codes=(3, 4), quick=True)
    lines = md.strip().splitlines()
    assert len(lines) == 4 and lines[2].startswith("| 3 | slight | 0.88 | 7.5 |")
    assert "nan" not in md.lower()
