"""The projected camera model against the rendered camera + TagDetector, paired on the same states and
the same ToF/IMU readings (ihrcf_env.experiments.camera_validation), both sensor presets, held to
the acceptance bounds of issue 10 (~40 s on a quiet core).

Errors within a trajectory are strongly correlated (a hovering drone keeps its corner errors, in
both modes), so trajectories, not frames, are the independent samples. Two small fixed sets:

* **single-frame estimators and detection**: 80 starts of 3 frames (0.45-3 m, offsets to half the
  view), four projected replicas: detection rate within 3 percentage points, corner RMS within
  10 %, per-axis MAE of IHRCF and ATDA within +-25 % (90 % bootstrap intervals ~+-15 %);
* **the fused filter**: 4 trajectories of 30 frames: it converges and stays valid on projected
  corners as on rendered ones. Its accuracy is not testable in a minute: over 1.5 s its error is
  mostly the convergence transient seeded by the first ATDA attitudes, so single trajectories
  decide its MAE (here one rendered trajectory diverging moves it by a factor of 5); the large
  run (60 trajectories of 40 frames per preset) is in the issue's report.
"""

from __future__ import annotations

import numpy as np
import pytest

from ihrcf_env.experiments.camera_validation import (
    DETECTION_TOLERANCE,
    MAE_TOLERANCE,
    CameraValidation,
    validate_camera_model,
)

PRESETS = ("ideal", "realistic")


@pytest.fixture(scope="module")
def single_frame() -> CameraValidation:
    return validate_camera_model(
        trajectories=80, frames=3, seed=1, replicas=4, altitudes=(0.45, 3.0), offset_fraction=0.5
    )


@pytest.fixture(scope="module")
def filtered() -> CameraValidation:
    return validate_camera_model(
        trajectories=4, frames=30, seed=2, replicas=2, altitudes=(0.6, 1.6), offset_fraction=0.3
    )


@pytest.mark.parametrize("preset", PRESETS)
def test_single_frame_estimators_and_detection(single_frame: CameraValidation, preset: str) -> None:
    v = single_frame.presets[preset]
    report = single_frame.markdown()
    assert v.frames == 240
    assert abs(v.detection["projected"] - v.detection["rendered"]) <= DETECTION_TOLERANCE, report
    assert v.corner_rms["projected"] == pytest.approx(v.corner_rms["rendered"], rel=0.10), report
    for est in ("ihrcf", "atda"):
        assert v.paired[est] >= 30, (est, v.paired)
        assert np.all(np.abs(v.ratio(est) - 1.0) <= MAE_TOLERANCE), (est, report)
    assert v.paired["fused"] == 0  # 3 frames: the filter has not converged
    assert v.failures() == []


@pytest.mark.parametrize("preset", PRESETS)
def test_fused_filter_runs_on_projected_corners(filtered: CameraValidation, preset: str) -> None:
    """The fused filter converges and stays valid on the projected corners as on the rendered ones
    (its accuracy needs the large run: over 1.5 s its error is mostly the convergence transient
    seeded by the first ATDA attitudes, and one diverging trajectory of four can move its MAE by a
    factor of 5 either way)."""
    v = filtered.presets[preset]
    assert abs(v.detection["projected"] - v.detection["rendered"]) <= DETECTION_TOLERANCE
    assert v.paired["fused"] >= 60
    assert v.valid["projected"]["fused"] == pytest.approx(v.valid["rendered"]["fused"], rel=0.1)
    assert np.all(np.isfinite(v.mae["projected"]["fused"]))


def test_report(single_frame: CameraValidation) -> None:
    text = single_frame.markdown()
    assert "sensor_preset='ideal'" in text and "sensor_preset='realistic'" in text
    assert "90 % interval" in text and "fused (no paired valid frames)" in text
    for v in single_frame.presets.values():
        for est in ("ihrcf", "atda"):
            ci = v.ratio_ci[est]
            assert ci.shape == (2, 6) and np.all(ci[0] <= ci[1])


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="preset"):
        validate_camera_model(presets=("foggy",), trajectories=1, frames=1)
    with pytest.raises(ValueError, match="frames"):
        validate_camera_model(trajectories=1, frames=0)
    with pytest.raises(ValueError, match="altitudes"):
        validate_camera_model(trajectories=1, frames=1, altitudes=(0.1, 2.0))
