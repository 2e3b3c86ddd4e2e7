"""The projected camera model against the rendered camera + TagDetector, paired on the same states and
the same ToF/IMU readings (ihrcf_env.experiments.camera_validation), both sensor presets (~50 s).

Errors within a trajectory are strongly correlated (a hovering drone keeps its corner errors, in
both modes), so trajectories, not frames, are the independent samples, and a minute of rendering
buys ~120 of them. At that size one axis's MAE ratio has a sampling spread of ~8-10 % (measured:
the same states with another projected noise draw moved single ratios by 10 %), so 24 per-axis
ratios cannot all be held to +-25 % without the test failing on noise. What is held here:

* **detection rate** within 3 percentage points and **corner RMS** within 10 % (both presets);
* **IHRCF and ATDA**, 120 starts of 4 frames (the first two fed but not scored, so ATDA has its
  flip prior), 1-3 m: per estimator the mean of its six axis ratios within +-25 % (spread ~4 %),
  every single axis within +-40 %;
* **the fused filter**, 3 trajectories of 30 frames: it converges and stays valid on projected
  corners as on rendered ones (over 1.5 s its error is mostly the convergence transient seeded by
  the first ATDA attitudes; one trajectory can move its MAE by a factor of 5).

Per-axis +-25 % for all three estimators is the large run's job
(``python -m ihrcf_env.experiments.camera_validation --trajectories 60 --frames 40 --replicas 3``,
~4 min; its table is in the issue's report).
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
        trajectories=120,
        frames=4,
        warmup=2,
        seed=1,
        replicas=2,
        altitudes=(1.0, 3.0),
        offset_fraction=0.5,
        estimators=("ihrcf", "atda"),
    )


@pytest.fixture(scope="module")
def filtered() -> CameraValidation:
    return validate_camera_model(
        trajectories=3, frames=30, seed=2, replicas=1, altitudes=(0.6, 1.6), offset_fraction=0.3
    )


@pytest.mark.parametrize("preset", PRESETS)
def test_single_frame_estimators_and_detection(single_frame: CameraValidation, preset: str) -> None:
    v = single_frame.presets[preset]
    report = single_frame.markdown()
    assert v.frames == 240
    assert abs(v.detection["projected"] - v.detection["rendered"]) <= DETECTION_TOLERANCE, report
    assert v.corner_rms["projected"] == pytest.approx(v.corner_rms["rendered"], rel=0.10), report
    for est in ("ihrcf", "atda"):
        assert v.paired[est] >= 10, (est, v.paired)  # realistic IHRCF: rarely valid at 1-3 m (VL53L1X)
        ratio = v.ratio(est)
        assert abs(float(ratio.mean()) - 1.0) <= MAE_TOLERANCE, (est, report)
        assert np.all(np.abs(ratio - 1.0) <= 0.40), (est, report)


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
    assert "90 % interval" in text and "| fused" not in text
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
    with pytest.raises(ValueError, match="warmup"):
        validate_camera_model(trajectories=1, frames=2, warmup=2)
    with pytest.raises(ValueError, match="estimators"):
        validate_camera_model(trajectories=1, frames=2, estimators=("ekf",))
