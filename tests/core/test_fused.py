"""The fused estimator on synthetic sequences of known answer (no simulator).

Every frame is made from a deck pose and a drone pose in the world: the tag corners by an exact
pinhole projection (plus pixel noise), the four ranges where the beams meet the deck plane (plus
range noise and dropouts), and the IMU sample of the drone (attitude, body rates, specific force;
ideal or with BMI088-like noise, biases and an attitude-filter error). The truth is the deck pose in
the body frame.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest

from ihrcf_env.core.constants import GRAVITY
from ihrcf_env.core.estimators import (
    DeckPoseSource,
    EstimatorConfig,
    FusedEstimator,
    FusedParams,
    ImuSample,
    PoseEstimate,
    SensorFrame,
    build_estimators,
    ihrcf_estimate,
)
from ihrcf_env.core.estimators.imm_deck import DeckImm
from ihrcf_env.core.frames import (
    body_pose_to_cam,
    euler_from_matrix,
    matrix_from_euler,
    quat_from_matrix,
    rotation_angle,
    wrap_angle,
)
from ihrcf_env.core.rig import SensorRig, intrinsics_from_fov, tag_corners_deck

RIG = SensorRig()
K = intrinsics_from_fov(512, 512, math.radians(60))  # f = 443.4 px
TAG = 0.4
HZ = 20.0
DEG = math.pi / 180

Pose = tuple[np.ndarray, np.ndarray]  # (R (3, 3), p (3,)) in the world


def touch_pixels(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The exact range -> touch-pixel table of the rig (beams parallel to the optical axis)."""
    pts = np.column_stack([RIG.sensor_xy_cam, r]) @ K.T
    return pts[:, :2] / pts[:, 2:3], np.ones(4, dtype=bool)


def observe(R_bd: np.ndarray, p_bd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact corners (4, 2) px and ranges (4,) m of a deck pose in the body frame."""
    R_cd, t_cd = body_pose_to_cam(R_bd, p_bd, RIG.camera_position)
    x = tag_corners_deck(TAG) @ R_cd.T + t_cd
    p = x @ K.T
    n = R_cd[:, 2]
    ranges = (n @ t_cd - RIG.sensor_xy_cam @ n[:2]) / n[2]
    return p[:, :2] / p[:, 2:3], ranges


def rotvec_matrix(e: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad)."""
    angle = float(np.linalg.norm(e))
    if angle < 1e-15:
        return np.eye(3)
    k = e / angle
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * Kx + (1 - math.cos(angle)) * Kx @ Kx


@dataclass
class NoisyImu:
    """BMI088-like accelerometer and gyro (white noise, turn-on bias, bias random walk) and an
    attitude filter's error (tilt error Gauss-Markov 0.5 deg over 5 s, heading drift ~1 deg/min)."""

    rng: np.random.Generator
    accel_density: float = 0.0019  # m/s^2/sqrt(Hz)
    accel_turn_on: float = 0.2  # m/s^2
    accel_walk: float = 0.002  # m/s^2/sqrt(s)
    gyro_density: float = 0.014 * DEG
    gyro_turn_on: float = 1.0 * DEG
    tilt_sigma: float = 0.5 * DEG
    tilt_tau: float = 5.0
    yaw_drift: float = 1.0 * DEG / 60

    def __post_init__(self) -> None:
        self.b_acc = self.rng.normal(0, self.accel_turn_on, 3)
        self.b_gyro = self.rng.normal(0, self.gyro_turn_on, 3)
        self.tilt = self.rng.normal(0, self.tilt_sigma, 2)
        self.drift = self.yaw_drift * (1 if self.rng.random() < 0.5 else -1)

    def sample(self, t: float, dt: float, R_wb: np.ndarray, omega: np.ndarray, f: np.ndarray) -> ImuSample:
        phi = math.exp(-dt / self.tilt_tau)
        self.tilt = phi * self.tilt + self.tilt_sigma * math.sqrt(1 - phi * phi) * self.rng.normal(size=2)
        self.b_acc = self.b_acc + self.accel_walk * math.sqrt(dt) * self.rng.normal(size=3)
        error = rotvec_matrix(np.array([self.tilt[0], self.tilt[1], self.drift * t]))
        return ImuSample(
            quat_from_matrix(error @ R_wb),
            omega + self.b_gyro + self.gyro_density / math.sqrt(dt) * self.rng.normal(size=3),
            f + self.b_acc + self.accel_density / math.sqrt(dt) * self.rng.normal(size=3),
        )


@dataclass
class Run:
    """Frames, truths (deck pose in the body frame) and the fused estimates of one sequence."""

    frames: list[SensorFrame]
    R_true: list[np.ndarray]
    p_true: list[np.ndarray]
    estimates: list[PoseEstimate]
    ihrcf: list[PoseEstimate]

    @property
    def valid(self) -> np.ndarray:
        return np.array([e.valid for e in self.estimates])

    def errors(self, estimates: list[PoseEstimate] | None = None) -> np.ndarray:
        """(n, 6) |error|: mm, mm, mm, deg, deg, deg (NaN where invalid)."""
        out = np.full((len(self.frames), 6), np.nan)
        for i, (e, R, p) in enumerate(
            zip(estimates or self.estimates, self.R_true, self.p_true, strict=True)
        ):
            if e.valid:
                out[i, :3] = np.abs(e.position - p) * 1000
                out[i, 3:] = np.degrees(np.abs(wrap_angle(e.euler - euler_from_matrix(R))))
        return out

    def angle_errors(self) -> np.ndarray:
        """(n,) rotation angle between the estimate and the truth, deg (NaN where invalid)."""
        return np.array(
            [
                math.degrees(rotation_angle(e.rotation, R)) if e.valid else np.nan
                for e, R in zip(self.estimates, self.R_true, strict=True)
            ]
        )


def still_deck(t: float) -> Pose:
    return matrix_from_euler(0.03, -0.02, 0.3), np.zeros(3)


def hovering_drone(t: float) -> Pose:
    return np.eye(3), np.array([0.02, -0.01, 1.0])


def paper_like_deck(t: float) -> Pose:
    """A slow deck like the simulator's "paper" profile (periods of 20-45 s)."""
    w = 2 * math.pi
    rpy = (
        9 * DEG * math.sin(w * t / 43.3) + 4 * DEG * math.sin(w * t / 18.6),
        8 * DEG * math.sin(w * t / 32.5),
        0.2 + 6 * DEG * math.sin(w * t / 26.0),
    )
    p = np.array([0.02 * math.sin(w * t / 30), 0.02 * math.sin(w * t / 43), 0.035 * math.sin(w * t / 21.7)])
    return matrix_from_euler(*rpy), p


def simulate(
    seconds: float,
    deck: Callable[[float], Pose] = still_deck,
    drone: Callable[[float], Pose] = hovering_drone,
    *,
    seed: int = 0,
    sigma_px: float = 0.2,
    sigma_r: float = 0.01,
    dropout: float = 0.0,
    imu: str = "ideal",  # "ideal", "noisy" or "none"
    lost: Callable[[float], bool] = lambda t: False,
    estimator: FusedEstimator | None = None,
    corrupt: Callable[[int, SensorFrame], SensorFrame] | None = None,
) -> Run:
    """Fly ``seconds`` at 20 Hz and feed every frame to ``estimator`` (default: a new one, with K)."""
    rng = np.random.default_rng(seed)
    est = estimator if estimator is not None else FusedEstimator(touch_pixels, RIG, TAG, K)
    noisy = NoisyImu(np.random.default_rng(seed + 1000)) if imu == "noisy" else None
    h = 1e-3
    dt = 1 / HZ
    run = Run([], [], [], [], [])
    for k in range(int(round(seconds * HZ)) + 1):
        t = k * dt
        R_wd, p_wd = deck(t)
        R_wb, p_wb = drone(t)
        R_bd, p_bd = R_wb.T @ R_wd, R_wb.T @ (p_wd - p_wb)
        corners, ranges = observe(R_bd, p_bd)
        corners = corners + rng.normal(0, sigma_px, (4, 2))
        ranges = ranges + rng.normal(0, sigma_r, 4)
        ok = rng.random(4) >= dropout
        ranges = np.where(ok, ranges, 4.0)
        # drone kinematics by central differences: acceleration (world), body rates
        acc = (drone(t + h)[1] - 2 * p_wb + drone(t - h)[1]) / (h * h)
        dR = (drone(t + h)[0] - drone(t - h)[0]) / (2 * h)
        W = R_wb.T @ dR
        omega = np.array([W[2, 1], W[0, 2], W[1, 0]])
        f = R_wb.T @ (acc + np.array([0.0, 0.0, GRAVITY]))
        if imu == "none":
            sample = None
        elif noisy is not None:
            sample = noisy.sample(t, dt, R_wb, omega, f)
        else:
            sample = ImuSample(quat_from_matrix(R_wb), omega, f)
        frame = SensorFrame(
            time=t, corners=None if lost(t) else corners, ranges=ranges, ranges_valid=ok, imu=sample
        )
        if corrupt is not None:
            frame = corrupt(k, frame)
        run.frames.append(frame)
        run.R_true.append(R_bd)
        run.p_true.append(p_bd)
        run.estimates.append(est.update(frame))
        run.ihrcf.append(
            ihrcf_estimate(frame.corners, frame.ranges, frame.ranges_valid, touch_pixels, RIG, TAG)
            if frame.corners is not None
            else PoseEstimate.invalid("lost")
        )
    return run


def mae(errors: np.ndarray) -> np.ndarray:
    return np.nanmean(errors, axis=0)


# ------------------------------------------------------------------------------------------ basics


def test_is_a_registered_deck_pose_source() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    assert isinstance(est, DeckPoseSource) and est.name == "fused"
    cfg = EstimatorConfig(rig=RIG, tag_size=TAG, K=K, dist=None, touch_pixels=touch_pixels)
    built = build_estimators(cfg, ["fused"])["fused"]
    assert isinstance(built, FusedEstimator) and built.params == FusedParams()
    custom = FusedParams(min_updates=3)
    cfg = dataclasses.replace(cfg, fused=custom)
    assert build_estimators(cfg, ["fused"])["fused"].params is custom  # type: ignore[attr-defined]


def test_params_are_checked() -> None:
    for bad in (
        {"tof_sigma": 0.0},
        {"tof_sigma": math.nan},
        {"accel_noise": -1.0},
        {"min_updates": 0},
        {"min_updates": 2.5},
        {"refit": 1},
        {"gate_probability": 1.0},
        {"accel_hold": "start"},
        {"lost_timeout": 0.0},
    ):
        with pytest.raises((ValueError, TypeError)):
            FusedParams(**bad)
    with pytest.raises(TypeError, match="params"):
        FusedEstimator(touch_pixels, RIG, TAG, K, params={"min_updates": 3})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_residual"):
        FusedEstimator(touch_pixels, RIG, TAG, K, max_residual=0.0)


# ------------------------------------------------------------------------------- static deck


def test_static_deck_converges_then_beats_single_frames() -> None:
    run = simulate(10.0)
    valid = run.valid
    # not valid before convergence, with the reason; valid from min_updates frames on
    n0 = FusedParams().min_updates
    assert not valid[: n0 - 1].any()
    assert all(e.reason.startswith("converging: ") for e in run.estimates[: n0 - 1])
    assert run.estimates[0].reason == f"converging: 1/{n0} updates"
    assert valid[n0 + 5 :].all()
    late = slice(100, None)
    fused = mae(run.errors()[late])
    single = mae(run.errors(run.ihrcf)[late])
    # IHRCF alone, sigma_r = 10 mm: ~3 deg tilt, ~4 mm depth per frame; fused: far below
    assert np.all(fused[:3] < 0.5 * single[:3]), (fused, single)
    assert np.all(fused[3:5] < 0.1 * single[3:5]), (fused, single)
    assert np.all(fused[:3] < 2.0) and np.all(fused[3:] < 0.25), fused


def test_range_noise_is_estimated_online() -> None:
    noisy = FusedEstimator(touch_pixels, RIG, TAG, K)
    simulate(6.0, sigma_r=0.01, estimator=noisy)
    assert 0.007 < noisy.range_sigma < 0.014
    exact = FusedEstimator(touch_pixels, RIG, TAG, K)
    run = simulate(6.0, sigma_r=0.0, estimator=exact)
    assert exact.range_sigma < 1e-4
    # exact ranges: the fused tilt follows IHRCF's (exact) tilt, not ATDA's (0.2 px corners)
    fused, single = mae(run.errors()[40:]), mae(run.errors(run.ihrcf)[40:])
    assert np.all(fused[3:5] < 1.2 * single[3:5] + 0.005), (fused, single)
    assert np.all(fused[:3] < 1.2 * single[:3] + 0.05), (fused, single)


def test_ihrcf_only_without_camera_matrix() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG)  # no K: no ATDA
    run = simulate(10.0, estimator=est)
    assert run.valid[40:].all()
    fused, single = mae(run.errors()[100:]), mae(run.errors(run.ihrcf)[100:])
    assert np.all(fused < 0.5 * single), (fused, single)
    assert not any(name.startswith("atda") for name, _ in est.diagnostics["accepted"])


# ------------------------------------------------------------------------------- moving deck


def ramp_deck(t: float) -> Pose:
    """Constant-rate tilt: roll 3 deg/s and pitch -2 deg/s through level, heave 2 cm/s."""
    return matrix_from_euler(3 * DEG * (t - 4), -2 * DEG * (t - 4), 0.4), np.array([0.0, 0.0, 0.02 * (t - 4)])


def test_constant_rate_tilt_is_tracked_without_growing_lag() -> None:
    run = simulate(8.0, ramp_deck, sigma_r=0.005)
    err = run.errors()
    mid, late = mae(err[60:110]), mae(err[110:])
    assert np.all(late[3:] < 0.3) and np.all(late[:3] < 2.0), late
    assert np.all(late[3:] < 1.5 * mid[3:] + 0.05), (mid, late)  # no lag building up
    # and no bias: the signed roll error averages out
    signed = [
        math.degrees(float(wrap_angle(e.euler[0] - euler_from_matrix(R)[0])))
        for e, R in zip(run.estimates[110:], run.R_true[110:], strict=True)
    ]
    assert abs(np.mean(signed)) < 0.1


def test_slow_deck_like_the_paper_profile() -> None:
    run = simulate(30.0, paper_like_deck, seed=3)
    fused, single = mae(run.errors()[20:]), mae(run.errors(run.ihrcf)[20:])
    assert np.all(fused[:3] < 2.0) and np.all(fused[3:] < 0.5), fused
    assert np.all(fused[3:5] < 0.15 * single[3:5]), (fused, single)


# -------------------------------------------------------------------------------- drone motion


def spinning_drone(t: float) -> Pose:
    """Yaw at 90 deg/s with 1 Hz roll and 0.7 Hz pitch wobbles of 10 and 8 deg; 5 cm, 0.5 Hz sway."""
    R = matrix_from_euler(
        10 * DEG * math.sin(2 * math.pi * t), 8 * DEG * math.sin(2 * math.pi * 0.7 * t), 0.5 * math.pi * t
    )
    return R, np.array([0.05 * math.sin(math.pi * t), 0.0, 1.0])


def test_fast_drone_rotation_passes_through_the_imu_without_lag() -> None:
    still = simulate(6.0, still_deck, hovering_drone, seed=1)
    run = simulate(6.0, still_deck, spinning_drone, seed=1)
    assert run.valid[20:].all()
    ang, ang_still = run.angle_errors()[20:], still.angle_errors()[20:]
    # the body-frame deck yaw turns by 90 deg/s and its tilt by up to ~60 deg/s: one frame of lag
    # alone would be 3-4.5 deg; the fused output is as good as with a still drone
    assert np.max(ang) < 0.6 and np.mean(ang) < 1.5 * np.mean(ang_still) + 0.03, (ang.max(), ang.mean())
    pos, pos_still = mae(run.errors()[20:])[:3], mae(still.errors()[20:])[:3]
    assert np.all(pos < 1.5 * pos_still + 0.3), (pos, pos_still)


def test_without_imu_the_body_frame_is_the_filter_frame() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    run = simulate(10.0, paper_like_deck, imu="none", estimator=est, seed=2)
    assert run.valid[20:].all()
    assert np.all(mae(run.errors()[40:])[3:] < 0.5) and np.all(mae(run.errors()[40:])[:3] < 2.0)
    # a spinning drone without IMU is another matter: the filter cannot tell it from the deck
    spin = simulate(6.0, still_deck, spinning_drone, imu="none", seed=1)
    with_imu = simulate(6.0, still_deck, spinning_drone, seed=1)
    bad = spin.angle_errors()[40:]
    assert (~spin.valid[40:]).mean() > 0.5 or np.nanmean(bad) > 10 * np.mean(with_imu.angle_errors()[40:])


# --------------------------------------------------------------------------------- tag lost


def test_short_gap_is_predicted_long_gap_invalidates_and_recovers() -> None:
    p = FusedParams()

    def lost(t: float) -> bool:
        return 3.0 <= t < 3.5 or 5.0 <= t < 7.0

    run = simulate(10.0, paper_like_deck, lost=lost)
    t = np.array([f.time for f in run.frames])
    valid = run.valid
    err = run.errors()
    # short gap (0.5 s < timeout): still valid, predicted on the IMU, small error
    short = (t >= 3.0) & (t < 3.5)
    assert valid[short].all()
    assert np.all(np.nanmax(err[short], axis=0)[3:] < 0.6) and np.all(np.nanmax(err[short], axis=0)[:3] < 4)
    # long gap: valid until the timeout, then invalid ("tag lost"), then not initialised
    gap = (t >= 5.0) & (t < 7.0)
    before = gap & (t - 4.95 < p.lost_timeout - 1e-6)  # 4.95 s: the last frame with the tag
    after = gap & (t - 4.95 > p.lost_timeout + 1e-6)
    assert valid[before].all() and not valid[after].any()
    first_after = int(np.flatnonzero(after)[0])
    assert "tag lost for" in run.estimates[first_after].reason
    assert all(run.estimates[i].reason == "not initialised: tag not found" for i in np.flatnonzero(after)[1:])
    # back: re-initialised, converging, then valid and accurate again
    back = int(np.flatnonzero(t >= 7.0)[0])
    back += next(i for i, e in enumerate(run.estimates[back:]) if not e.reason.startswith("not initialised"))
    assert run.estimates[back].reason.startswith("converging: 1/")
    assert valid[back + p.min_updates + 5 :].all()
    assert np.all(mae(err[back + 40 :])[3:] < 0.5)


# ------------------------------------------------------------------------------ robustness


def test_outliers_are_rejected() -> None:
    def corrupt(k: int, frame: SensorFrame) -> SensorFrame:
        if k in (60, 61):  # one range 3 cm long (15 sigma): IHRCF's plane tilts by ~6 deg
            r = frame.ranges.copy()
            r[0] += 0.03
            return dataclasses.replace(frame, ranges=r)
        if k in (90, 120):  # corners 15 px off: both estimators see the tag 3 cm aside
            assert frame.corners is not None
            return dataclasses.replace(frame, corners=frame.corners + 15.0)
        return frame

    clean = simulate(8.0, sigma_r=0.002)
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    rejected: dict[int, list[str]] = {}
    estimates = []
    for k, frame in enumerate(clean.frames):
        estimates.append(est.update(corrupt(k, frame)))
        rejected[k] = [name for name, _ in est.diagnostics["rejected"]]
    assert "ihrcf.tilt" in rejected[60] and "ihrcf.tilt" in rejected[61]
    assert "ihrcf.position" in rejected[90] and "ihrcf.position" in rejected[120]
    err, ref = clean.errors(estimates), clean.errors()
    for k in (60, 61, 90, 120):
        assert estimates[k].valid
        assert np.all(err[k, :3] < ref[k, :3] + 0.5) and np.all(err[k, 3:] < ref[k, 3:] + 0.1), (
            k,
            err[k],
            ref[k],
        )
    assert sum(bool(v) for k, v in rejected.items() if k not in (60, 61, 90, 120)) <= 3  # good frames pass


def test_persistent_jump_reinitialises() -> None:
    """The deck jumps by 10 cm (e.g. a wrong tag or a filter gone astray): after max_rejections frames
    the filter starts again from the measurements."""
    p = FusedParams()

    def deck(t: float) -> Pose:
        R, pos = still_deck(t)
        return R, pos + (np.array([0.1, 0.0, 0.0]) if t >= 4.0 else 0.0)

    run = simulate(8.0, deck, sigma_r=0.005)
    jump = int(4.0 * HZ)
    err = run.errors()
    assert np.nanmax(err[jump + p.max_rejections + p.min_updates + 10 :, :3]) < 5.0
    assert run.valid[-40:].all()


def test_noisy_imu() -> None:
    run = simulate(30.0, paper_like_deck, seed=4, imu="noisy")
    valid = run.valid
    assert valid[20:].mean() > 0.98
    fused, single = mae(run.errors()[40:]), mae(run.errors(run.ihrcf)[40:])
    assert np.all(fused[:3] < 2.5) and np.all(fused[3:] < 0.6), fused
    assert np.all(fused[3:5] < 0.2 * single[3:5]), (fused, single)


def test_noisy_imu_and_moving_drone() -> None:
    def drone(t: float) -> Pose:
        R, p = spinning_drone(t)
        roll, pitch, _ = 0.3 * euler_from_matrix(R)
        return matrix_from_euler(roll, pitch, 0.2 * t), p

    run = simulate(12.0, paper_like_deck, drone, seed=5, imu="noisy")
    assert run.valid[20:].mean() > 0.95
    fused = mae(run.errors()[40:])
    assert np.all(fused[:3] < 4.0) and np.all(fused[3:] < 1.0), fused


def test_dropouts_and_three_ranges() -> None:
    run = simulate(10.0, paper_like_deck, dropout=0.2, seed=6)
    assert run.valid[20:].all()
    assert np.all(mae(run.errors()[40:])[3:] < 0.5)


def test_bad_frames_never_give_nan() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    good = simulate(2.0, estimator=est).frames
    assert est.update(good[-1]).valid or True
    R_bd, p_bd = still_deck(0)[0], np.array([-0.02, 0.01, -1.0])
    corners, ranges = observe(R_bd, p_bd)
    imu = good[-1].imu
    t = good[-1].time
    ok = np.ones(4, bool)
    nan_imu = ImuSample(np.full(4, np.nan), np.zeros(3), np.zeros(3))
    zero_imu = ImuSample(np.zeros(4), np.zeros(3), np.zeros(3))
    cases = [
        (
            "nan corners",
            SensorFrame(t + 0.05, np.full((4, 2), np.nan), ranges, np.ones(4, bool), imu=imu),
            "",
        ),
        ("nan ranges", SensorFrame(t + 0.10, corners, np.full(4, np.nan), np.ones(4, bool), imu=imu), ""),
        ("inf ranges", SensorFrame(t + 0.15, corners, np.full(4, np.inf), np.ones(4, bool), imu=imu), ""),
        ("nan imu", SensorFrame(t + 0.2, corners, ranges, ok, imu=nan_imu), "non-finite IMU sample"),
        ("zero quaternion", SensorFrame(t + 0.2, corners, ranges, ok, imu=zero_imu), "zero IMU quaternion"),
        ("backwards", SensorFrame(t - 1.0, corners, ranges, ok, imu=imu), "time went backwards"),
        ("unknown time", SensorFrame(math.nan, corners, ranges, np.ones(4, bool), imu=imu), ""),
        ("no imu", SensorFrame(t + 0.35, corners, ranges, np.ones(4, bool)), ""),
        ("huge ranges", SensorFrame(t + 0.4, corners, np.full(4, 1e9), np.ones(4, bool), imu=imu), ""),
        ("huge corners", SensorFrame(t + 0.45, corners * 1e9, ranges, np.ones(4, bool), imu=imu), ""),
        ("no valid ranges", SensorFrame(t + 0.5, corners, ranges, np.zeros(4, bool), imu=imu), ""),
        ("far future", SensorFrame(t + 1e6, corners, ranges, np.ones(4, bool), imu=imu), ""),
    ]
    for name, frame, reason in cases:
        out = est.update(frame)
        for a in (out.position, out.euler, out.rotation):
            assert np.all(np.isfinite(a)), name
        assert math.isfinite(out.residual), name
        if reason:
            assert not out.valid and reason in out.reason, (name, out.reason)
    rng = np.random.default_rng(0)
    for k in range(200):  # random garbage
        frame = SensorFrame(
            t + 1e6 + 0.05 * k,
            None if k % 7 == 0 else corners + rng.normal(0, 50, (4, 2)) * (k % 3),
            ranges * rng.uniform(0.0, 3.0, 4),
            rng.random(4) > 0.3,
            imu=ImuSample(rng.normal(size=4), rng.normal(size=3), rng.normal(0, 20, 3)),
        )
        out = est.update(frame)
        assert np.all(np.isfinite(out.position)) and np.all(np.isfinite(out.euler))


def test_unknown_time_uses_the_nominal_interval() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    run = simulate(4.0, estimator=FusedEstimator(touch_pixels, RIG, TAG, K))
    outs = [est.update(dataclasses.replace(f, time=math.nan)) for f in run.frames]
    assert outs[-1].valid
    np.testing.assert_allclose(outs[-1].position, run.estimates[-1].position, atol=1e-9)


def test_reset_forgets_everything() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    run = simulate(5.0, estimator=est, sigma_r=0.0)
    assert run.estimates[-1].valid and est.initialised and est.range_sigma < 1e-3
    est.reset()
    assert not est.initialised and est.range_sigma == pytest.approx(FusedParams().tof_sigma)
    assert est.diagnostics == {}
    again = est.update(run.frames[0])  # an earlier time is fine after a reset
    assert not again.valid and again.reason.startswith("converging: 1/")
    # the same sequence again gives the same answers: nothing survived the reset
    est.reset()
    outs = [est.update(f) for f in run.frames]
    for a, b in zip(outs, run.estimates, strict=True):
        assert a.valid == b.valid and a.reason == b.reason
        np.testing.assert_array_equal(a.position, b.position)


def test_options_no_refit_no_atda_position_trapezoid() -> None:
    no_refit = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(refit=False))
    run = simulate(10.0, paper_like_deck, estimator=no_refit, seed=7)
    assert np.all(mae(run.errors()[40:])[3:] < 0.5)
    assert "ihrcf.attitude" in [n for n, _ in no_refit.diagnostics["accepted"]]  # IHRCF's own yaw
    ranges_only = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(use_atda_position=False))
    run = simulate(10.0, paper_like_deck, estimator=ranges_only, seed=7)
    names = [n for n, _ in ranges_only.diagnostics["accepted"]]
    assert "atda.position" not in names and "ihrcf.position" in names
    assert np.all(mae(run.errors()[40:])[:3] < 2.0)
    trapezoid = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(accel_hold="trapezoid"))
    run = simulate(6.0, still_deck, spinning_drone, estimator=trapezoid, seed=1)
    assert np.mean(run.angle_errors()[20:]) < 0.2


def test_default_fuses_atda_depth() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    simulate(2.0, estimator=est)
    assert {"atda.attitude", "atda.position", "ihrcf.position", "ihrcf.tilt", "ihrcf.yaw"} <= {
        n for n, _ in est.diagnostics["accepted"]
    }


# ------------------------------------------------------------------------ common-mode range offset


def _add_range_offset(offset: float) -> Callable[[int, SensorFrame], SensorFrame]:
    def corrupt(k: int, frame: SensorFrame) -> SensorFrame:
        return dataclasses.replace(frame, ranges=frame.ranges + offset)

    return corrupt


def test_common_mode_range_offset_is_estimated_against_atda_depth() -> None:
    """+4 mm on all four ranges, exact (ATDA-consistent) corners: without the offset state the
    range-based depth keeps the offset; with it the offset is learnt from ATDA's depth."""
    corrupt = _add_range_offset(0.004)
    off = FusedEstimator(touch_pixels, RIG, TAG, K)
    run_off = simulate(20.0, estimator=off, sigma_r=0.002, corrupt=corrupt)
    on = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(range_offset_sigma=0.004))
    run_on = simulate(20.0, estimator=on, sigma_r=0.002, corrupt=corrupt)
    late = slice(200, None)
    z_off, z_on = mae(run_off.errors()[late])[2], mae(run_on.errors()[late])[2]
    assert off.range_offset == 0.0 and 2.5 < z_off < 5.0, z_off  # ATDA's depth pulls a little
    assert z_on < 1.0, z_on
    assert 3.0e-3 < on.range_offset < 5.0e-3, on.range_offset
    # the rest of the pose is no worse
    assert np.all(mae(run_on.errors()[late])[:2] < mae(run_off.errors()[late])[:2] + 0.2)
    assert np.all(mae(run_on.errors()[late])[3:] < mae(run_off.errors()[late])[3:] + 0.02)


def test_range_offset_state_off_by_default_is_bit_for_bit() -> None:
    a = simulate(3.0, estimator=FusedEstimator(touch_pixels, RIG, TAG, K), seed=3)
    b = simulate(
        3.0,
        estimator=FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(range_offset_sigma=0.0)),
        seed=3,
    )
    for ea, eb in zip(a.estimates, b.estimates, strict=True):
        np.testing.assert_array_equal(ea.position, eb.position)
        np.testing.assert_array_equal(ea.euler, eb.euler)


def test_shared_frame_work_is_computed_once_and_changes_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    """IHRCF, ATDA and the fused filter on one frame: IHRCF's corners and ATDA's IPPE solutions are
    computed once per frame (SensorFrame.memo), and every estimate equals the one of an estimator
    that ran alone on its own copy of the frame."""
    from ihrcf_env.core.estimators import atda as atda_mod
    from ihrcf_env.core.estimators import ihrcf as ihrcf_mod

    calls = {"ihrcf": 0, "atda": 0}
    real_corners, real_cands = ihrcf_mod.ihrcf_corners, atda_mod.atda_candidates

    def count(name: str, fn: Callable) -> Callable:
        def wrapped(*a: object, **k: object) -> object:
            calls[name] += 1
            return fn(*a, **k)

        return wrapped

    monkeypatch.setattr(ihrcf_mod, "ihrcf_corners", count("ihrcf", real_corners))
    monkeypatch.setattr(atda_mod, "atda_candidates", count("atda", real_cands))
    cfg = EstimatorConfig(rig=RIG, tag_size=TAG, K=K, dist=None, touch_pixels=touch_pixels, max_residual=0.01)
    shared = build_estimators(cfg, ("ihrcf", "atda", "fused"))
    alone = {n: build_estimators(cfg, (n,))[n] for n in ("ihrcf", "atda", "fused")}
    run = simulate(1.0, paper_like_deck, estimator=FusedEstimator(touch_pixels, RIG, TAG, K))
    for logged in run.frames:  # fresh frames: simulate()'s own filter filled the logged ones' memo
        frame = SensorFrame(logged.time, logged.corners, logged.ranges, logged.ranges_valid, imu=logged.imu)
        before = dict(calls)
        out = {n: s.update(frame) for n, s in shared.items()}
        assert calls["ihrcf"] - before["ihrcf"] == 1 and calls["atda"] - before["atda"] == 1
        for n, source in alone.items():
            copy = SensorFrame(frame.time, frame.corners, frame.ranges, frame.ranges_valid, imu=frame.imu)
            ref = source.update(copy)
            assert ref.valid == out[n].valid and ref.reason == out[n].reason
            np.testing.assert_array_equal(ref.position, out[n].position)
            np.testing.assert_array_equal(ref.rotation, out[n].rotation)


def test_motion_gives_the_deck_velocity_and_normal_rate() -> None:
    """FusedEstimator.motion(): None before convergence; on the constant-rate ramp deck (heave
    2 cm/s, roll 3 deg/s, pitch -2 deg/s) under a hovering drone, the deck's relative velocity and
    the rate of its normal (world axes), within 5 mm/s and 0.01 1/s."""
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    assert est.motion() is None
    simulate(0.1, ramp_deck, estimator=est)
    assert est.motion() is None  # converging
    est = FusedEstimator(touch_pixels, RIG, TAG, K)
    simulate(8.0, ramp_deck, sigma_r=0.005, estimator=est)
    motion = est.motion()
    assert motion is not None
    velocity, normal_rate = motion
    np.testing.assert_allclose(velocity, [0.0, 0.0, 0.02], atol=0.005)
    h = 1e-4
    true_rate = (ramp_deck(8.0 + h)[0][:, 2] - ramp_deck(8.0 - h)[0][:, 2]) / (2 * h)
    np.testing.assert_allclose(normal_rate, true_rate, atol=0.01)
    assert np.linalg.norm(true_rate) > 0.05  # the test can fail: the deck tilts at ~0.06 rad/s


def _textbook_imm_update(kf, z, lo, hi, R):
    """Reference: gate on the fully moment-matched combined estimate, then each model's Joseph-form
    Kalman update and Bayes on the model probabilities (the formulas, no shortcuts)."""
    from ihrcf_env.core.estimators.imm import wrap_angles as _wrap

    n = len(kf.mu)
    ref = kf.X[int(np.argmax(kf.mu))]
    D = kf.X - ref
    D[:, :3] = _wrap(D[:, :3]) if kf.angles else D[:, :3]
    x = ref + kf.mu @ D
    E = D - kf.mu @ D
    P = sum(kf.mu[i] * (kf.Ps[i] + np.outer(E[i], E[i])) for i in range(n))
    H = np.zeros((hi - lo, 9))
    H[np.arange(hi - lo), np.arange(lo, hi)] = 1.0
    nu = z - H @ x
    nu = _wrap(nu) if kf.angles else nu
    d2 = float(nu @ np.linalg.solve(H @ P @ H.T + R, nu))
    X, Ps, lik = [], [], []
    for i in range(n):
        S = H @ kf.Ps[i] @ H.T + R
        K = kf.Ps[i] @ H.T @ np.linalg.inv(S)
        v = z - H @ kf.X[i]
        v = _wrap(v) if kf.angles else v
        IKH = np.eye(9) - K @ H
        X.append(kf.X[i] + K @ v)
        Ps.append(IKH @ kf.Ps[i] @ IKH.T + K @ R @ K.T)
        lik.append(math.exp(-0.5 * float(v @ np.linalg.solve(S, v))) / math.sqrt(np.linalg.det(S)))
    mu = kf.mu * np.array(lik)
    return d2, np.array(X), np.array(Ps), mu / mu.sum()


@pytest.mark.parametrize("angles", [False, True])
@pytest.mark.parametrize("rows", [(0, 3), (0, 2), (2, 3)])
def test_imm_update_is_the_textbook_update(angles: bool, rows: tuple[int, int]) -> None:
    # The filter's update is written for tiny matrices (gate on the measured block only, P - K S K^T);
    # it must equal the full formulas to rounding.
    from ihrcf_env.core.estimators.imm import Imm as _Imm
    from ihrcf_env.core.estimators.imm import largest_eigenvalue as _largest_eigenvalue

    rng = np.random.default_rng(11)
    kf = _Imm(
        (0.5, 0.2, 0.1),
        [np.full(3, d) for d in (0.001, 0.01, 0.1)],
        np.full(3, 0.01),
        30.0,
        0.0,
        angles=angles,
    )
    for _ in range(5):  # distinct model states, covariances and probabilities
        kf.predict(0.05, None, np.diag([1e-4, 2e-4, 0.0]))
        z = rng.normal(0, 0.05, 3) + (3.1 if angles else 0.0)
        kf.update(z, (0, 3), np.diag([1e-3, 2e-3, 3e-3]), None)
    lo, hi = rows
    A = rng.normal(size=(hi - lo, hi - lo))
    R = A @ A.T * 1e-4 + np.eye(hi - lo) * 1e-5
    z = kf.x[lo:hi] + rng.normal(0, 0.01, hi - lo)
    d2_ref, X_ref, Ps_ref, mu_ref = _textbook_imm_update(kf, z, lo, hi, R)
    ok, d2 = kf.update(z, rows, R, 1e9)
    assert ok
    assert d2 == pytest.approx(d2_ref, rel=1e-9)
    np.testing.assert_allclose(kf.X, X_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(kf.Ps, Ps_ref, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(kf.mu, mu_ref, rtol=1e-9)
    C = kf.value_cov
    assert _largest_eigenvalue(C) == pytest.approx(float(np.linalg.eigvalsh(C)[-1]), rel=1e-12)


def test_imm_constant_value_noise_equals_per_step_noise() -> None:
    # A constant q_value given to the constructor is folded into the cached process noise; it must
    # equal giving it to every predict (to rounding).
    from ihrcf_env.core.estimators.imm import Imm as _Imm

    q = np.diag([1e-4, 2e-4, 0.0])
    drifts = [np.full(3, d) for d in (0.001, 0.01, 0.1)]
    a = _Imm((0.5, 0.2, 0.1), drifts, np.full(3, 0.01), 30.0, 0.0, q_value=q)
    b = _Imm((0.5, 0.2, 0.1), drifts, np.full(3, 0.01), 30.0, 0.0)
    rng = np.random.default_rng(3)
    for _ in range(20):
        u = rng.normal(size=3)
        a.predict(0.05, u)
        b.predict(0.05, u, q)
        z = rng.normal(0, 0.05, 3)
        assert a.update(z, (0, 3), np.diag([1e-3, 2e-3, 3e-3]), None)[0]
        assert b.update(z, (0, 3), np.diag([1e-3, 2e-3, 3e-3]), None)[0]
    np.testing.assert_allclose(a.X, b.X, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a.Ps, b.Ps, rtol=1e-10, atol=1e-18)
    np.testing.assert_allclose(a.mu, b.mu, rtol=1e-10)


# -------------------------------------------------------------- narrow-band deck model (option)


def ship_deck(t: float) -> Pose:
    """A sum of sines in a Froude-scaled ship's band: periods 1.0-1.6 s, heave about 2 cm, roll
    and pitch about 1 deg, sway and surge about 1 cm."""
    w = 2 * math.pi
    rpy = (
        1.0 * DEG * math.sin(w * t / 1.35 + 0.3) + 0.4 * DEG * math.sin(w * t / 1.05 + 1.0),
        1.2 * DEG * math.sin(w * t / 1.25 + 2.0) + 0.5 * DEG * math.sin(w * t / 1.6),
        0.3 + 0.3 * DEG * math.sin(w * t / 1.5),
    )
    p = np.array(
        [
            0.01 * math.sin(w * t / 1.4 + 0.5),
            0.008 * math.sin(w * t / 1.2 + 1.5),
            0.02 * math.sin(w * t / 1.3 + 0.7) + 0.008 * math.sin(w * t / 1.0 + 2.2),
        ]
    )
    return matrix_from_euler(*rpy), p


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("deck_model", "ship"),
        ("deck_model", None),
        ("deck_periods", ()),
        ("deck_periods", (0.0,)),
        ("deck_periods", (1.0, math.inf)),
        ("deck_periods", (1.0,) * 9),
        ("deck_periods", [1.0]),
        ("deck_periods", (True,)),
        ("deck_damping", 0.0),
        ("deck_damping", 1.5),
        ("deck_accel_sigma", -0.1),
        ("deck_angle_accel_sigma", math.nan),
        ("deck_oscillator_drift", -1.0),
    ],
)
def test_deck_model_options_are_checked_by_name(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        FusedParams(**{field: value})  # type: ignore[arg-type]


def test_default_deck_model_is_unchanged_bit_for_bit() -> None:
    # estimates of the default filter on a ship-like deck with a noisy IMU, as computed before the
    # deck-model option existed
    before = [
        [-0.020868844258078, -0.000898736735453, -1.014941030185137,
         -0.00998593042584, -0.008632572068535, 0.303628485695446],
        [-0.021378029393306, 0.017915714256538, -0.994796676521246,
         0.000119402755231, 0.013426546103463, 0.295290412272411],
        [-0.020727670430257, 0.005319479151543, -1.008479769396474,
         -0.002013022025583, -0.005064914342986, 0.305344299214343],
        [-0.00482030199018, -0.010889907129386, -0.918703265837525,
         0.020969527465943, -0.030251172675812, 0.301531429107177],
    ]  # fmt: skip
    assert FusedParams().deck_model == "kinematic"
    run = simulate(3.0, ship_deck, seed=1, imu="noisy")
    got = [np.concatenate([run.estimates[i].position, run.estimates[i].euler]) for i in (12, 25, 40, 60)]
    np.testing.assert_allclose(got, before, rtol=0, atol=2e-15)
    assert int(run.valid.sum()) == 52


@pytest.mark.parametrize("seed", [1, 2])
def test_oscillator_deck_model_follows_a_ship_like_deck(seed: int) -> None:
    # the kinematic models lag a deck swaying at 1-1.6 s; the oscillators follow it: the position
    # error is at most a quarter of the kinematic filter's, the tilt error no larger (+10 %)
    errors, valid = {}, {}
    for model in ("kinematic", "oscillator"):
        est = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(deck_model=model))
        run = simulate(6.0, ship_deck, seed=seed, imu="noisy", estimator=est)
        errors[model], valid[model] = mae(run.errors()[60:]), run.valid[20:].mean()
    kin, osc = errors["kinematic"], errors["oscillator"]
    assert np.all(osc[:3] < 0.25 * kin[:3]), (osc, kin)
    assert np.all(osc[3:5] < 1.1 * kin[3:5]), (osc, kin)
    assert np.all(osc[:3] < 2.0), osc
    assert valid["oscillator"] == 1.0 and valid["oscillator"] >= valid["kinematic"]


def test_oscillator_deck_model_on_a_still_deck() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(deck_model="oscillator"))
    run = simulate(10.0, estimator=est)
    assert run.valid[FusedParams().min_updates + 5 :].all()
    fused = mae(run.errors()[100:])
    assert np.all(fused[:3] < 2.0) and np.all(fused[3:] < 0.25), fused
    assert est.motion() is not None and est._pos is not None and est._pos.X.shape[1] == 15


def test_oscillator_transition_reduces_to_the_kinematic_model_and_has_the_stated_level() -> None:
    from ihrcf_env.core.estimators.imm import Imm as _Imm
    from ihrcf_env.core.estimators.imm_deck import oscillator_transition

    dt, drift, white = 0.05, np.array([0.02, 0.03, 0.01]), np.array([0.003, 0.004, 0.005])
    F, Q = oscillator_transition(dt, 1.2, 0.1, False, np.full(3, 0.3), drift, white)
    _, Ft0, Q0 = _Imm((1.0, 1.0, 1.0), [drift], white, 30.0, 0.0)._model(dt)
    np.testing.assert_allclose(F[:9, :9], Ft0.T, rtol=0, atol=1e-12)
    np.testing.assert_allclose(Q[:9, :9], Q0[0], rtol=1e-9, atol=1e-18)
    assert not F[:9, 9:].any() and not Q[9:, 9:].any()
    # coupled: the stationary variances of the displacement and rate are sigma^2 / w^4, sigma^2 / w^2
    sigma, period = np.array([0.3, 0.5, 0.2]), 1.2
    F, Q = oscillator_transition(dt, period, 0.1, True, sigma, drift, white)
    idx = np.r_[9:15]
    Fo, Qo = F[np.ix_(idx, idx)], Q[np.ix_(idx, idx)]
    P = np.zeros((6, 6))
    for _ in range(4000):
        P = Fo @ P @ Fo.T + Qo
    w = 2 * math.pi / period
    np.testing.assert_allclose(np.diag(P)[:3], sigma**2 / w**4, rtol=0.02)
    np.testing.assert_allclose(np.diag(P)[3:], sigma**2 / w**2, rtol=0.02)


def test_deck_imm_set_oscillators_checks_and_changes_the_model() -> None:
    from ihrcf_env.core.estimators.imm_deck import DeckImm

    kf = DeckImm(
        (1.0, 0.5, 0.5), [np.full(3, 0.01)], np.full(3, 0.003), 30.0, 0.0, (1.0, 1.5), 0.1,
        np.full(3, 0.3), np.full(3, 0.01),
    )  # fmt: skip
    assert kf.X.shape == (3, 15) and kf.Ps.shape == (3, 15, 15)
    F1 = kf._model(0.05)[1].copy()
    with pytest.raises(ValueError, match="periods"):
        kf.set_oscillators((1.0,), np.full(3, 0.3))
    with pytest.raises(ValueError, match="accel_sigma"):
        kf.set_oscillators((1.0, 2.0), np.full(2, 0.3))
    kf.set_oscillators((1.1, 2.0), np.full(3, 0.3))
    assert not np.allclose(kf._model(0.05)[1], F1)


def test_set_deck_oscillation_centres_the_banks_on_identified_dynamics() -> None:
    est = FusedEstimator(touch_pixels, RIG, TAG, K, params=FusedParams(deck_model="oscillator"))
    with pytest.raises(ValueError, match="deck_model"):
        FusedEstimator(touch_pixels, RIG, TAG, K).set_deck_oscillation(heave=(1.0, 0.01))
    for bad in ((0.05, 0.01), (math.nan, 0.01), (1.0, -0.01), (1.0, math.inf)):
        with pytest.raises(ValueError, match="heave"):
            est.set_deck_oscillation(heave=bad)
        with pytest.raises(ValueError, match="tilt"):
            est.set_deck_oscillation(tilt=bad)
    seen = []

    def inform(k: int, frame: SensorFrame) -> SensorFrame:
        if k == 20:  # 1 s in: the filters are live
            est.set_deck_oscillation(heave=(2.4, 0.02), tilt=(0.6, 0.01))
            seen.append((est._pos, est._att))
        return frame

    # the tag is lost from 1.2 to 2.6 s (longer than lost_timeout): the filters are created again
    simulate(3.5, ship_deck, estimator=est, corrupt=inform, lost=lambda t: 1.2 <= t < 2.6)
    pos, att = seen[0]
    assert isinstance(pos, DeckImm) and isinstance(att, DeckImm)
    bank = np.array(FusedParams().deck_periods)
    np.testing.assert_allclose(pos.periods, bank * 2.0)
    np.testing.assert_allclose(att.periods, bank * 0.5)
    w = 2 * math.pi / 2.4
    np.testing.assert_allclose(pos.accel_sigma, [0.3, 0.3, 0.02 * w * w])
    assert isinstance(est._pos, DeckImm) and est._pos is not pos
    np.testing.assert_allclose(est._pos.periods, bank * 2.0)
    est.reset()
    simulate(0.5, ship_deck, estimator=est)
    assert isinstance(est._pos, DeckImm)
    np.testing.assert_allclose(est._pos.periods, bank)


def test_observation_options_take_the_oscillator() -> None:
    from ihrcf_env.config.observation import check_observation_options

    osc = FusedParams(deck_model="oscillator")
    assert check_observation_options(fused_params=osc).fused_params is osc
