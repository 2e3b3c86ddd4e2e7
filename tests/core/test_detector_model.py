"""Tests for ihrcf_env.core.detector_model (pure: no simulator)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from ihrcf_env.core import detector_model as dm
from ihrcf_env.core.detector_model import (
    FIT_COMMAND,
    CornerTrack,
    DetectorModel,
    DetectorModelError,
    DetectorSamples,
    QualityParams,
    corner_basis,
    default_detector_model_path,
    fit_quality,
    project_points,
    tag_features,
)

W = H = 512


def params(**kw: float) -> QualityParams:
    base: dict = {
        "mean_radial": (-0.2, -0.06, -0.07, 0.0, 0.05, 0.0, 0.3, 0.0, 0.02, 0.0, 0.0, 0.0),
        "log_sd_radial": (math.log(0.2), -0.3, 0.2, 0.0, 0.2, 0.0, 0.5, 0.1, 0.0, 0.0, 0.0, 0.0),
        "mean_tangential": (0.0, 0.0, 0.0, 0.19, 0.0, -0.03, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0),
        "log_sd_tangential": (math.log(0.27), -0.4, 0.35, 0.0, 0.1, 0.0, 0.2, 0.1, 0.0, 0.0, 0.0, 0.0),
        "corr_max": 0.9,
        "corr_length_px": 0.15,
        "min_margin_px": 0.3,
        "band_low_px": 0.0,
        "band_high_px": 5.0,
        "band_fail_prob": 0.9,
        "size50_px": 11.0,
        "size_width_px": 1.5,
        "min_cos_view": 0.11,
        "miss_prob": 0.0,
    }
    base.update(kw)
    return QualityParams(**base)


def model(**kw: float) -> DetectorModel:
    return DetectorModel({"ideal": params(**kw), "realistic": params(noise_gain=20.0, blur_gain=0.05, **kw)})


def square(
    centre: tuple[float, float] = (256.0, 255.0), side: float = 100.0, angle: float = 0.3
) -> np.ndarray:
    """A clockwise (image axes, y down) square tag, corners in TagDetector order."""
    h = side / 2
    local = np.array([[-h, -h], [h, -h], [h, h], [-h, h]])
    c, s = math.cos(angle), math.sin(angle)
    return local @ np.array([[c, s], [-s, c]]) + np.asarray(centre)


def features(corners: np.ndarray, **kw: object) -> dm.TagFeatures:
    ctr = corners.mean(axis=0)
    quiet = ctr + (corners - ctr) * dm.QUIET_ZONE_SCALE
    args: dict = {"cos_view": 0.95, "width": W, "height": H}
    args.update(kw)
    return tag_features(corners, quiet, **args)


# -- geometry -----------------------------------------------------------------------------------
def test_project_points_matches_opencv_with_distortion() -> None:
    rng = np.random.default_rng(0)
    P = np.column_stack([rng.uniform(-0.5, 0.5, (20, 2)), rng.uniform(0.8, 3.0, 20)])
    K = np.array([[443.4, 0.0, 256.0], [0.0, 443.4, 255.0], [0.0, 0.0, 1.0]])
    for k in ((0.0, 0.0), (-0.05, 0.01)):
        ref, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), K, np.array([k[0], k[1], 0.0, 0.0, 0.0]))
        np.testing.assert_allclose(project_points(P, K, k), ref.reshape(-1, 2), atol=1e-9)


def test_corner_basis_of_a_square() -> None:
    c = square(angle=0.0)
    radial, tangential, basis, side = corner_basis(c)
    out = (c - c.mean(axis=0)) / np.linalg.norm(c - c.mean(axis=0), axis=1, keepdims=True)
    np.testing.assert_allclose(radial, out, atol=1e-12)  # outward along the diagonals
    np.testing.assert_allclose((radial * tangential).sum(axis=1), 0.0, atol=1e-12)
    np.testing.assert_allclose(side, 100.0)
    np.testing.assert_allclose(basis[:, 0], 1.0)
    np.testing.assert_allclose(basis[:, 1], 0.0, atol=1e-12)  # log(100 / 100)
    np.testing.assert_allclose(basis[:, 2], 1.0)  # cos(4 a) of axis-aligned edges
    np.testing.assert_allclose(basis[:, 6], 0.0, atol=1e-12)  # cos of the right angles
    # vectorised over leading dimensions: the same numbers
    r2, _, b2, _ = corner_basis(np.stack([c, c]))
    np.testing.assert_array_equal(r2[1], radial)
    np.testing.assert_array_equal(b2[0], basis)


def test_features_margins() -> None:
    f = features(square(centre=(60.0, 255.0), side=100.0, angle=0.0))
    assert f.margin == pytest.approx(60.0 - 50.0 + 0.5)
    assert f.quiet_margin == pytest.approx(60.0 - 62.5 + 0.5)
    assert f.min_side == pytest.approx(100.0)


# -- file ---------------------------------------------------------------------------------------
def test_save_load_round_trip(tmp_path: Path) -> None:
    m = DetectorModel(model().qualities, fit={"seed": 3, "note": "x"})
    path = m.save(tmp_path / "sub" / "model.json")
    back = DetectorModel.load(path)
    assert back.to_dict() == m.to_dict()
    assert back.source == str(path)
    assert back.params("realistic") == m.params("realistic")


def test_shipped_model_loads() -> None:
    m = DetectorModel.load()
    assert m.source == str(default_detector_model_path())
    for q in ("ideal", "realistic"):
        prm = m.params(q)
        assert -0.4 < prm.mean_radial[0] < 0.0  # corners come out inside the tag
        assert 0.1 < math.exp(prm.log_sd_radial[0]) < 0.5
    assert path_size(default_detector_model_path()) < 20_000


def path_size(p: Path) -> int:
    return p.stat().st_size


@pytest.mark.parametrize(
    "content",
    [
        "{not json",
        "[]",
        json.dumps({"format": "something else", "format_version": 1, "qualities": {}}),
        "CORRUPT",
    ],
)
def test_corrupt_file_names_file_and_fit_command(tmp_path: Path, content: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(DetectorModelError) as e:
        DetectorModel.load(path)
    assert str(path) in str(e.value) and FIT_COMMAND in str(e.value)


def test_bad_parameter_in_file_names_it(tmp_path: Path) -> None:
    d = model().to_dict()
    d["qualities"]["ideal"]["corr_max"] = 2.0
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(d))
    with pytest.raises(DetectorModelError, match="corr_max") as e:
        DetectorModel.load(path)
    assert str(path) in str(e.value) and FIT_COMMAND in str(e.value)
    del d["qualities"]["realistic"]
    d["qualities"]["ideal"]["corr_max"] = 0.5
    path.write_text(json.dumps(d))
    with pytest.raises(DetectorModelError, match="realistic"):
        DetectorModel.load(path)


def test_missing_file_names_file_and_fit_command(tmp_path: Path) -> None:
    path = tmp_path / "nope.json"
    with pytest.raises(DetectorModelError) as e:
        DetectorModel.load(path)
    assert str(path) in str(e.value) and FIT_COMMAND in str(e.value)
    assert isinstance(e.value, ValueError)


def test_bad_params_raise_naming_them() -> None:
    with pytest.raises(ValueError, match="mean_radial"):
        params(mean_radial=(0.0,) * 11)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="miss_prob"):
        params(miss_prob="0.1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="band_high_px"):
        params(band_low_px=3.0, band_high_px=1.0)
    with pytest.raises(ValueError, match="quality"):
        model().params("cinematic")


# -- the noise ----------------------------------------------------------------------------------
@pytest.mark.parametrize("quality", ["ideal", "realistic"])
def test_noise_statistics_match_the_model(quality: str) -> None:
    m = model()
    prm = m.params(quality)
    f = features(square(angle=0.2), noise_ratio=0.01, blur_px=2.0)
    rng = np.random.default_rng(1)
    n = 4000
    e = np.array([m.corners(f, rng, quality)[0] for _ in range(n)]) - f.corners  # type: ignore[operator]
    er = (e * f.radial).sum(-1)
    et = (e * f.tangential).sum(-1)
    mean, sd = prm.error_moments(f.basis, f.side, f.noise_ratio, f.blur_px)
    for k, comp in enumerate((er, et)):
        np.testing.assert_allclose(comp.mean(axis=0), mean[:, k], atol=4 * sd[:, k].max() / math.sqrt(n))
        np.testing.assert_allclose(comp.std(axis=0), sd[:, k], rtol=0.06)
    # corners and components independent
    c = np.corrcoef(np.column_stack([er, et]).T)
    assert np.abs(c - np.eye(8)).max() < 0.07
    if quality == "realistic":  # noise and blur add variance
        assert np.all(sd > model().params("ideal").error_moments(f.basis, f.side)[1])


def test_correlation_is_a_field_over_the_image() -> None:
    """Across tracks: the correlation of a corner's error between two frames is
    corr_max exp(-(D / corr_length)^2) of its displacement D, and a corner back where it was gets
    its error back (a function of the position, not a chain of steps)."""
    m = model(corr_max=0.9, corr_length_px=0.15, band_fail_prob=0.0)
    c0 = square()
    rng = np.random.default_rng(2)
    n = 2000
    for step, expected in ((0.0, 0.9), (0.1, 0.9 * math.exp(-((0.1 / 0.15) ** 2))), (1.0, 0.0)):
        z = np.empty((n, 3))
        for k in range(n):
            track = dm.CornerTrack(rng)
            for j, shift in enumerate((0.0, step, 0.0)):
                f = features(c0 + np.array([shift, 0.0]))
                out, _ = m.corners(f, rng, "ideal", track)
                assert out is not None
                z[k, j] = float(((out - f.corners) * f.radial).sum(-1)[0])
        z = (z - z.mean(axis=0)) / z.std(axis=0)
        assert float((z[:, 0] * z[:, 1]).mean()) == pytest.approx(expected, abs=0.06)
        assert float((z[:, 0] * z[:, 2]).mean()) == pytest.approx(0.9, abs=0.06)  # back at the start
    # without a track: independent frames
    f = features(c0)
    z = np.array([((m.corners(f, rng)[0] - f.corners) * f.radial).sum(-1) for _ in range(2000)])  # type: ignore[operator]
    z = z - z.mean(axis=0)
    assert abs(float((z[1:] * z[:-1]).mean() / z.var())) < 0.06
    # the model's correlation function
    assert m.params("ideal").correlation(0.15) == pytest.approx(0.9 * math.exp(-1.0))


# -- failures -----------------------------------------------------------------------------------
def test_failure_rules() -> None:
    rng = np.random.default_rng(3)
    m = model(miss_prob=0.0, band_fail_prob=1.0)
    ok, reason = m.corners(features(square()), rng)
    assert ok is not None and reason == ""
    assert m.corners(features(square(centre=(-300.0, 255.0))), rng) == (None, dm.REASON_OUTSIDE)
    assert m.corners(features(square(centre=(40.0, 255.0), angle=0.0)), rng) == (None, dm.REASON_BORDER)
    # quiet zone's outer edge 2 px inside the image: in the band
    corners = square(centre=(64.5 - 0.5 + 2.0, 255.0), side=100.0, angle=0.0)
    f = features(corners)
    assert 0.0 <= f.quiet_margin < 5.0 and f.margin > 0.3
    assert m.corners(f, rng) == (None, dm.REASON_QUIET_ZONE)
    assert m.corners(features(square(), cos_view=0.05), rng) == (None, dm.REASON_OBLIQUE)
    assert m.corners(features(square(side=5.0)), rng) == (None, dm.REASON_SMALL)
    assert model(miss_prob=1.0).corners(features(square()), rng) == (None, dm.REASON_MISS)
    # probabilities: the band fails at band_fail_prob
    half = model(band_fail_prob=0.5)
    fails = sum(half.corners(f, rng)[0] is None for _ in range(2000))
    assert fails / 2000 == pytest.approx(0.5, abs=0.04)


def test_determinism_and_fixed_draws() -> None:
    m = model()
    frames = [features(square(centre=(256.0 + 3 * k, 255.0))) for k in range(5)]
    frames.append(features(square(centre=(-300.0, 255.0))))  # a failure: same draws
    outs = []
    for _ in range(2):
        rng, track = np.random.default_rng(7), CornerTrack(np.random.default_rng(8))
        outs.append([m.corners(f, rng, "realistic", track) for f in frames])
        assert rng.bit_generator.state == _after(7, len(frames))
    for (a, ra), (b, rb) in zip(*outs, strict=True):
        assert ra == rb
        assert (a is None and b is None) or np.array_equal(a, b)


def _after(seed: int, frames: int) -> dict:
    rng = np.random.default_rng(seed)
    for _ in range(frames):
        rng.standard_normal((4, 2))
        rng.random()
    return rng.bit_generator.state


# -- fitting ------------------------------------------------------------------------------------
def test_fit_recovers_a_known_model() -> None:
    """Synthetic frames drawn from a known model (tracks of slowly moving tags, some crossing the
    border, some small): the fit must give back its parameters."""
    truth = model(miss_prob=0.01, corr_max=0.8, corr_length_px=0.2)
    prm_true = truth.params("ideal")
    rng = np.random.default_rng(11)
    rows: dict[str, list] = {k: [] for k in ("c", "q", "det", "track")}
    for t in range(700):
        side = rng.uniform(40.0, 250.0) if t % 10 else rng.uniform(6.0, 20.0)
        centre = rng.uniform(-0.1 * W, 1.1 * W, 2) if t % 3 == 0 else rng.uniform(0.25 * W, 0.75 * W, 2)
        angle = rng.uniform(0, 2 * math.pi)
        velocity = rng.uniform(-0.3, 0.3, 2) if t % 2 else rng.uniform(-6.0, 6.0, 2)
        track = CornerTrack()
        for k in range(6):
            c = square(tuple(centre + k * velocity), side, angle)  # type: ignore[arg-type]
            f = features(c)
            out, _ = truth.corners(f, rng, "ideal", track)
            rows["c"].append(c)
            rows["q"].append(f.quiet_zone)
            rows["det"].append(out if out is not None else np.full((4, 2), np.nan))
            rows["track"].append(t)
    n = len(rows["c"])
    samples = DetectorSamples(
        corners=np.array(rows["c"]),
        quiet_zone=np.array(rows["q"]),
        cos_view=np.full(n, 0.95),
        noise_ratio=np.zeros((n, 4)),
        blur_px=np.zeros(n),
        detected=np.array(rows["det"]),
        track=np.array(rows["track"]),
        width=W,
        height=H,
    )
    prm, report = fit_quality(samples, with_extra=False)
    np.testing.assert_allclose(prm.mean_radial[:4], prm_true.mean_radial[:4], atol=0.02)
    np.testing.assert_allclose(prm.mean_tangential[:4], prm_true.mean_tangential[:4], atol=0.02)
    np.testing.assert_allclose(prm.log_sd_radial[:3], prm_true.log_sd_radial[:3], atol=0.06)
    assert prm.corr_max == pytest.approx(0.8, abs=0.08)
    assert prm.corr_length_px == pytest.approx(0.2, abs=0.05)
    assert prm.min_margin_px == pytest.approx(0.3, abs=0.3)
    assert prm.band_low_px == pytest.approx(0.0, abs=1.0) and prm.band_high_px == pytest.approx(5.0, abs=1.0)
    assert prm.band_fail_prob == pytest.approx(0.9, abs=0.1)
    assert prm.size50_px == pytest.approx(11.0, abs=1.5)
    assert prm.miss_prob == pytest.approx(0.01, abs=0.01)
    assert report["detection_rate_model"] == pytest.approx(report["detection_rate_rendered"], abs=0.02)


@pytest.mark.parametrize(
    "field",
    [
        "noise_gain",
        "blur_gain",
        "corr_max",
        "corr_length_px",
        "min_margin_px",
        "band_low_px",
        "band_high_px",
        "band_fail_prob",
        "size50_px",
        "size_width_px",
        "min_cos_view",
        "miss_prob",
        "mean_radial",
        "log_sd_tangential",
    ],
)
def test_a_400_digit_integer_in_the_file_names_the_field(tmp_path: Path, field: str) -> None:
    # Before: OverflowError (float(int)) escaped from DetectorModel.load, naming nothing.
    d = model().to_dict()
    huge = -(10**400)
    if field.startswith(("mean_", "log_sd_")):
        d["qualities"]["realistic"][field][3] = huge
        name = rf"{field}\[3\]"
    else:
        d["qualities"]["realistic"][field] = huge
        name = field
    path = tmp_path / "huge.json"
    path.write_text(json.dumps(d))
    with pytest.raises(DetectorModelError, match=rf"realistic.*{name}") as e:
        DetectorModel.load(path)
    assert str(path) in str(e.value) and FIT_COMMAND in str(e.value)


def test_a_huge_format_version_is_a_file_error(tmp_path: Path) -> None:
    d = model().to_dict()
    d["format_version"] = 10**400
    path = tmp_path / "v.json"
    path.write_text(json.dumps(d))
    with pytest.raises(DetectorModelError, match="format_version"):
        DetectorModel.load(path)


def test_json_nested_too_deeply_is_a_file_error(tmp_path: Path) -> None:
    # Before: RecursionError from json.loads.
    depth = 200_000
    path = tmp_path / "deep.json"
    path.write_text('{"fit": ' + "[" * depth + "]" * depth + "}")
    with pytest.raises(DetectorModelError, match="nested too deeply") as e:
        DetectorModel.load(path)
    assert str(path) in str(e.value) and FIT_COMMAND in str(e.value)
