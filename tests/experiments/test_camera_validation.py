"""The projected camera model against the rendered camera + TagDetector, paired on the same states and
the same ToF/IMU readings (ihrcf_env.experiments.camera_validation), both sensor presets. The
statistical comparisons render hundreds of frames: they are marked ``slow`` (``pytest -m slow``,
which ``.ci/run`` runs after the default tests).

Errors within a trajectory are strongly correlated (a hovering drone keeps its corner errors, in
both modes), so trajectories, not frames, are the independent samples. At 120 starts one axis's MAE
ratio has a sampling spread of ~8-10 % (ATDA's Y ratio was 1.27 there); at 360 starts ~5 %, and
every ratio of this fixed set is within 0.96-1.12 (90 % intervals within 0.90-1.22). Held here:

* **detection rate** within 3 percentage points and **corner RMS** within 10 % (both presets);
* **IHRCF and ATDA**, 360 starts of 4 frames (the first two fed but not scored, so ATDA has its
  flip prior), 1-3 m: **every axis's MAE ratio within +-25 %** (the issue's bound);
* **the fused filter**, 3 trajectories of 30 frames: it converges and stays valid on projected
  corners as on rendered ones. Its per-axis ratios need long trajectories and many of them (over
  1.5 s its error is mostly the convergence transient seeded by the first ATDA attitudes; one
  trajectory can move its MAE by a factor of 5): that is the large run's job
  (``python -m ihrcf_env.experiments.camera_validation --trajectories 200 --frames 40 --replicas 3
  --seed 1``, ~18 min per preset on one core; every ratio within 0.96-1.14, see the README).
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
        trajectories=360,
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


@pytest.mark.slow
@pytest.mark.parametrize("preset", PRESETS)
def test_single_frame_estimators_and_detection(single_frame: CameraValidation, preset: str) -> None:
    v = single_frame.presets[preset]
    report = single_frame.markdown()
    assert v.frames == 720
    assert abs(v.detection["projected"] - v.detection["rendered"]) <= DETECTION_TOLERANCE, report
    assert v.corner_rms["projected"] == pytest.approx(v.corner_rms["rendered"], rel=0.10), report
    for est in ("ihrcf", "atda"):
        assert v.paired[est] >= 10, (est, v.paired)  # realistic IHRCF: rarely valid at 1-3 m (VL53L1X)
        assert np.all(np.abs(v.ratio(est) - 1.0) <= MAE_TOLERANCE), (est, report)


@pytest.mark.slow
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


@pytest.mark.slow
def test_report(single_frame: CameraValidation) -> None:
    text = single_frame.markdown()
    assert "sensor_preset='ideal'" in text and "sensor_preset='realistic'" in text
    assert "90 % interval" in text and "p95 ratio" in text and "| fused" not in text
    for v in single_frame.presets.values():
        for est in ("ihrcf", "atda"):
            ci = v.ratio_ci[est]
            assert ci.shape == (2, 6) and np.all(ci[0] <= ci[1])
            for m in ("rendered", "projected"):  # the 95th percentile lies above the mean
                assert v.p95[m][est].shape == (6,) and np.all(v.p95[m][est] >= v.mae[m][est])


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
