"""The realistic camera model (CameraConfig(quality="realistic")): ideal mode unchanged, noise
statistics, determinism, blur, vignetting, background, detection and pose accuracy at the paper's
1 m hover with the shipped calibration."""

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.sensors import CameraConfig, ImagingParams
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.calibration import Calibration, default_calibration_path
from ihrcf_env.core.estimators import TagDetector
from ihrcf_env.core.frames import euler_from_matrix
from ihrcf_env.core.profiles import StaticProfile, paper_profile
from ihrcf_env.core.seeding import SeedStreams
from ihrcf_env.sim.sensors.imaging import (
    EpisodeImaging,
    RealisticImager,
    add_sensor_noise,
    blur_kernel,
    ground_homography,
    image_motion_px,
    make_texture,
    noise_sigma_lut,
    sky_mask,
    vignetting_gain,
)
from ihrcf_env.sim.world import World
from ihrcf_env.wrappers import estimator_from_calibration

REALISTIC = CameraConfig(quality="realistic")

#: A noiseless sensor (huge full well): isolates blur / vignetting / background from the noise.
NOISELESS = ImagingParams(full_well_e=1e12, read_noise_e=1e-6, ae_error=0.0)


def episode(**kw: float) -> EpisodeImaging:
    base = dict(
        light_direction=(0.0, 0.0, 1.0),
        ambient=0.6,
        diffuse=0.35,
        exposure_s=0.005,
        gain=1.0,
        brightness=1.0,
        texture_origin=(0.0, 0.0),
        texture_angle=0.0,
        drift=(0.0, 0.0),
    )
    base.update(kw)
    return EpisodeImaging(**base)  # type: ignore[arg-type]


def hover_world(
    camera: CameraConfig, seed: int = 0, frames: int = 10, make: Callable[..., World] = World
) -> World:
    """A world hovering 1 m over the paper's deck; ``make`` builds it (pass the ``make_world``
    fixture in a test: it closes the world at teardown)."""
    w = make(WorldConfig(camera=camera))
    w.reset(paper_profile(), horizon_s=frames / 20 + 2, altitude=1.0)
    w.reset_random(np.random.default_rng(seed))
    return w


def read_frames(
    make_world: Callable[..., World], camera: CameraConfig, seed: int, n: int = 3
) -> list[np.ndarray]:
    w = hover_world(camera, seed, n, make=make_world)
    rng = np.random.default_rng(seed)
    w.reset_random(rng)
    out = []
    for _ in range(n):
        w.step()
        out.append(w.sensing.read_sensors(rng, ("camera",))["image"])
    return out


# -- configuration ---------------------------------------------------------------------------------


def test_quality_is_validated():
    assert CameraConfig().quality == "ideal"
    with pytest.raises(ValueError, match="quality"):
        CameraConfig(quality="photoreal")
    with pytest.raises(TypeError, match="imaging"):
        CameraConfig(quality="realistic", imaging={"full_well_e": 1})  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="read_noise_e"):
        ImagingParams(read_noise_e=-1.0)
    with pytest.raises(ValueError, match="background"):
        ImagingParams(background="space")
    with pytest.raises(ValueError, match="scene_exposure_s"):
        ImagingParams(scene_exposure_s=(0.02, 0.001))


def test_default_parameters_follow_the_imx296_figures():
    ip = ImagingParams()
    assert "IMX296" in ip.sensor
    # SNRmax 40.3 dB and dynamic range 71.2 dB of the Pregius 3.45 um pixel (EMVA 1288)
    assert 10 * math.log10(ip.full_well_e) == pytest.approx(40.3, abs=0.05)
    assert 20 * math.log10(ip.full_well_e / ip.read_noise_e) == pytest.approx(71.2, abs=0.05)
    assert ip.electrons_per_dn(1.0) == pytest.approx(ip.full_well_e / 255)


# -- ideal mode unchanged --------------------------------------------------------------------------


def test_ideal_images_are_unchanged_bit_for_bit(make_world):
    """Default and explicit "ideal" read exactly the pre-realism render: one getCameraImage call
    with the config's light, no segmentation mask, RGB of the RGBA buffer; nothing drawn from the
    rng."""
    for cfg in (CameraConfig(), CameraConfig(quality="ideal")):
        w = hover_world(cfg, make=make_world)
        for _ in range(3):
            w.step()
        w.reset_random(SeedStreams(5))  # the world draws the episode's streams; the sensor none
        rng = np.random.default_rng(5)
        img = w.sensing.read_sensors(rng, ("camera",))["image"]
        assert rng.bit_generator.state == np.random.default_rng(5).bit_generator.state
        cam = w.camera
        assert cam is not None and cam.imager is None and cam.episode is None
        pos, R = w.drone_pose()
        eye, R_wc = cam.pose(pos, R)
        view = p.computeViewMatrix(
            eye.tolist(), (eye + R_wc[:, 2]).tolist(), (-R_wc[:, 1]).tolist(), physicsClientId=w.client
        )
        c = cam.config
        _, _, rgba, _, _ = p.getCameraImage(
            c.width,
            c.height,
            viewMatrix=view,
            projectionMatrix=cam._proj,
            shadow=0,
            lightDirection=list(c.light_direction),
            lightAmbientCoeff=c.ambient,
            lightDiffuseCoeff=c.diffuse,
            lightSpecularCoeff=c.specular,
            renderer=p.ER_TINY_RENDERER,
            flags=p.ER_NO_SEGMENTATION_MASK,
            physicsClientId=w.client,
        )
        before = np.asarray(rgba, dtype=np.uint8).reshape(c.height, c.width, 4)[:, :, :3]
        assert img.dtype == np.uint8 and np.array_equal(img, before)


def test_default_and_explicit_ideal_agree_with_distortion(make_world):
    a = read_frames(make_world, CameraConfig(distortion=(-0.05, 0.0)), seed=1, n=2)
    b = read_frames(make_world, CameraConfig(distortion=(-0.05, 0.0), quality="ideal"), seed=1, n=2)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


# -- noise model ------------------------------------------------------------------------------------


@pytest.mark.parametrize("gain", [1.0, 4.0, 8.0])
def test_noise_statistics_match_the_model_on_a_flat_patch(gain):
    """On flat patches the output's s.d. is sqrt(read^2 + S/g) in DN (+ 1/12 DN^2 of rounding)
    within 10 %, and its mean is the signal."""
    ip = ImagingParams()
    g = ip.electrons_per_dn(gain)
    lut = noise_sigma_lut(g, ip.read_noise_e)
    rng = np.random.default_rng(3)
    bank = rng.standard_normal((256 + 32, 256 + 32, 3), dtype=np.float32)
    for level in (20, 80, 150, 220):
        flat = np.full((256, 256, 3), level, np.uint8)
        out = add_sensor_noise(flat, lut, bank, (int(rng.integers(0, 33)), int(rng.integers(0, 33))), 1)
        expected = math.sqrt((ip.read_noise_e / g) ** 2 + level / g + 1 / 12)
        x = out.astype(np.float64)
        assert abs(x.mean() - level) < 0.1 * expected + 0.05, (gain, level, x.mean())
        assert x.std() == pytest.approx(expected, rel=0.10), (gain, level)


def test_noise_statistics_through_the_whole_pipeline():
    """A flat grey deck filling the frame, no vignetting, no motion: the camera image's s.d. is the
    model's for the episode's gain."""
    ip = replace(ImagingParams(), vignetting_exponent=0.0, ae_error=0.0)
    K = CameraConfig().intrinsics
    imager = RealisticImager(ip, K, 256, 256)
    rng = np.random.default_rng(0)
    imager.reset(rng, episode(gain=6.0))
    rgb = np.full((256, 256, 3), 120, np.uint8)
    seg = np.ones((256, 256), np.int32)
    img = imager.process(
        rgb, seg, np.array([0, 0, 2.0]), np.diag([1.0, -1.0, -1.0]), np.zeros(3), np.zeros(3), 1.0, 0.0, rng
    )
    g = ip.electrons_per_dn(6.0)
    expected = math.sqrt((ip.read_noise_e / g) ** 2 + 120 / g + 1 / 12)
    assert img.astype(float).mean() == pytest.approx(120, abs=0.2)
    assert img.astype(float).std() == pytest.approx(expected, rel=0.10)


def test_saturated_pixels_stay_at_full_scale_and_nothing_wraps():
    ip = replace(ImagingParams(), vignetting_exponent=0.0)
    imager = RealisticImager(ip, CameraConfig().intrinsics, 128, 128)
    rng = np.random.default_rng(0)
    imager.reset(rng, episode(gain=8.0, brightness=1.6))
    rgb = np.full((128, 128, 3), 250, np.uint8)
    rgb[:, :64] = 2
    img = imager.process(
        rgb,
        np.ones((128, 128), np.int32),
        np.array([0, 0, 2.0]),
        np.diag([1.0, -1.0, -1.0]),
        np.zeros(3),
        np.zeros(3),
        1.0,
        0.0,
        rng,
    )
    assert img.dtype == np.uint8 and img.shape == (128, 128, 3)
    assert np.all(img[:, 64:] == 255)  # 250 * 1.6 clips at full scale: no wrap-around, no noise
    assert img[:, :64].max() < 40  # dark side: noise around 3 DN, no wrap to 255


# -- determinism ------------------------------------------------------------------------------------


def test_same_seed_same_images_different_seed_different(make_world):
    a = read_frames(make_world, REALISTIC, seed=11)
    b = read_frames(make_world, REALISTIC, seed=11)
    c = read_frames(make_world, REALISTIC, seed=12)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not any(np.array_equal(x, y) for x, y in zip(a, c, strict=True))
    assert not np.array_equal(a[0], a[1])  # the noise changes from frame to frame


def test_episodes_vary_within_their_ranges(make_world):
    ip = ImagingParams()
    w = make_world(WorldConfig(camera=REALISTIC))
    cam = w.camera
    assert cam is not None
    eps = []
    for seed in range(20):
        cam.reset(np.random.default_rng(seed))
        assert cam.episode is not None
        eps.append(cam.episode)
    for ep in eps:
        assert ep.exposure_s <= ip.max_exposure_s + 1e-12
        assert 1.0 <= ep.gain <= ip.max_gain
        assert ip.ambient[0] <= ep.ambient <= ip.ambient[1]
        assert ip.diffuse[0] <= ep.diffuse <= ip.diffuse[1]
        el = math.degrees(math.asin(ep.light_direction[2]))
        assert ip.light_elevation_deg[0] - 1e-9 <= el <= ip.light_elevation_deg[1] + 1e-9
        assert 0.6 < ep.brightness < 1.5
    assert len({round(ep.gain, 6) for ep in eps}) > 5
    assert len({ep.light_direction for ep in eps}) == 20


# -- blur, vignetting, background ----------------------------------------------------------------------


def test_blur_grows_with_speed():
    K = CameraConfig().intrinsics
    R_wc = np.diag([1.0, -1.0, -1.0])  # looking straight down
    lengths = []
    for v in (0.0, 0.05, 0.5, 2.0):
        du, dv = image_motion_px(K, R_wc, np.array([v, 0, 0]), np.zeros(3), 1.5, 0.005)
        lengths.append(math.hypot(du, dv))
    assert lengths[0] == 0.0 and lengths[1] < 0.3 < lengths[2] < lengths[3]
    assert lengths[3] == pytest.approx(K[0, 0] * 2.0 / 1.5 * 0.005)
    # a pitch rate blurs like a translation: w = v / Z
    du, dv = image_motion_px(K, R_wc, np.zeros(3), np.array([0, 2.0 / 1.5, 0]), 1.5, 0.005)
    assert math.hypot(du, dv) == pytest.approx(lengths[3])
    k = blur_kernel(3.0, 4.0)
    assert k.sum() == pytest.approx(1.0) and np.allclose(k, k[::-1, ::-1], atol=1e-6)

    imager = RealisticImager(NOISELESS, K, 256, 256)
    rng = np.random.default_rng(0)
    imager.reset(rng, episode())
    checker = ((np.indices((256, 256)).sum(axis=0) // 8) % 2 * 200 + 20).astype(np.uint8)
    rgb = np.repeat(checker[..., None], 3, axis=2)
    sharpness = []
    for v in (0.0, 0.5, 1.0, 3.0):
        img = imager.process(
            rgb.copy(),
            np.ones((256, 256), np.int32),
            np.array([0, 0, 1.5]),
            R_wc,
            np.array([v, 0, 0]),
            np.zeros(3),
            1.5,
            0.0,
            rng,
        )
        sharpness.append(float(np.abs(np.diff(img[:, :, 0].astype(float), axis=1)).mean()))
    assert sharpness[0] > sharpness[1] > sharpness[2] > sharpness[3]


def test_vignetting_darkens_corners():
    K = CameraConfig().intrinsics
    v = vignetting_gain(K, 512, 512, 2.0)
    cy, cx = int(round(K[1, 2])), int(round(K[0, 2]))
    assert v[cy, cx] == pytest.approx(1.0)
    r2 = ((511 - K[0, 2]) ** 2 + (511 - K[1, 2]) ** 2) / K[0, 0] ** 2
    assert v[511, 511] == pytest.approx(1 / (1 + r2), rel=1e-5)  # cos^2 of the field angle
    assert max(v[0, 0], v[0, 511], v[511, 0], v[511, 511]) < 0.65
    imager = RealisticImager(NOISELESS, K, 512, 512)
    rng = np.random.default_rng(0)
    imager.reset(rng, episode())
    img = imager.process(
        np.full((512, 512, 3), 200, np.uint8),
        np.ones((512, 512), np.int32),
        np.array([0, 0, 2.0]),
        np.diag([1.0, -1.0, -1.0]),
        np.zeros(3),
        np.zeros(3),
        2.0,
        0.0,
        rng,
    )
    assert img[cy, cx, 0] == 200
    assert img[:20, :20].mean() < 0.65 * 200 and img[-20:, -20:].mean() < 0.65 * 200


def test_ground_homography_is_the_pinhole_projection_of_the_plane():
    K = CameraConfig().intrinsics
    rng = np.random.default_rng(1)
    for _ in range(5):
        eye = np.array([*rng.uniform(-1, 1, 2), rng.uniform(1.0, 3.0)])
        tilt = rng.uniform(-0.3, 0.3, 3)
        from ihrcf_env.core.frames import matrix_from_euler

        R_wc = matrix_from_euler(*tilt) @ np.diag([1.0, -1.0, -1.0])
        texel, origin, angle = 0.01, (rng.uniform(-1, 1), rng.uniform(-1, 1)), rng.uniform(0, 6)
        H = ground_homography(K, eye, R_wc, texel, origin, angle)
        for u, v in rng.uniform(0, 300, (4, 2)):
            c, s = math.cos(angle), math.sin(angle)
            a, b = (u + 0.5) * texel, (v + 0.5) * texel
            X = np.array([origin[0] + c * a - s * b, origin[1] + s * a + c * b, 0.0])
            pc = R_wc.T @ (X - eye)
            expected = (K @ pc)[:2] / pc[2]
            h = H @ np.array([u, v, 1.0])
            assert np.allclose(h[:2] / h[2], expected, atol=1e-6)


def test_sky_appears_only_when_the_horizon_is_in_view():
    K = CameraConfig().intrinsics
    from ihrcf_env.core.frames import matrix_from_euler

    down = np.diag([1.0, -1.0, -1.0])
    assert sky_mask(K, down, 512, 512) is None
    tilted = matrix_from_euler(0.0, math.radians(75), 0.0) @ down  # looking far forward
    mask = sky_mask(K, tilted, 512, 512)
    assert mask is not None and 0 < mask.mean() < 1


def test_texture_is_small_periodic_and_seeded():
    for kind in ("sea", "ground"):
        t = make_texture(kind, 256, 0)
        assert t.shape == (256, 256, 3) and t.dtype == np.uint8 and t.nbytes < 300_000
        assert t.std() > 5
        assert np.array_equal(t, make_texture(kind, 256, 0))
        assert not np.array_equal(t, make_texture(kind, 256, 1))
        # periodic: the wrap-around step is like any other neighbour step
        inner = np.abs(np.diff(t.astype(float), axis=1)).mean()
        wrap = np.abs(t[:, 0].astype(float) - t[:, -1].astype(float)).mean()
        assert wrap < 2 * inner + 1


def test_background_is_not_blank_and_the_deck_is_where_the_ideal_render_has_it(make_world):
    ideal = read_frames(make_world, CameraConfig(), seed=2, n=1)[0]
    real = read_frames(make_world, REALISTIC, seed=2, n=1)[0]
    background = np.all(ideal == ideal[0, 0], axis=2)  # the ideal render's blank background
    assert 0.2 < background.mean() < 0.9 and ideal[background].std() == 0
    assert real[background].astype(float).std() > 8.0
    assert abs(real[background].astype(float).mean() - float(ideal[0, 0].mean())) > 40


def test_realistic_camera_works_with_distortion(make_world):
    imgs = read_frames(make_world, CameraConfig(quality="realistic", distortion=(-0.05, 0.0)), seed=3, n=1)
    assert imgs[0].dtype == np.uint8 and TagDetector(0).detect(imgs[0]) is not None


# -- detection and accuracy at the paper's hover -----------------------------------------------------


@pytest.fixture(scope="module")
def hover_run():
    """200 frames (10 s) of the paper's hover (1 m, "paper" profile, 20 Hz) with the realistic
    camera and ideal ToF, estimated with the shipped calibration (made with the ideal camera)."""
    frames = 200
    w = hover_world(REALISTIC, seed=0, frames=frames)
    rng = np.random.default_rng(0)
    w.reset_random(rng)
    est = estimator_from_calibration(
        Calibration.load(default_calibration_path()), tag_size=0.4, tag_id=0, estimators=("ihrcf", "atda")
    )
    detected = 0
    errors: dict[str, list[np.ndarray]] = {"ihrcf": [], "atda": []}
    try:
        for _ in range(frames):
            w.step()
            obs = w.sensing.read_sensors(rng)
            frame = est.frame(obs["image"], obs["ranges"], np.asarray(obs["ranges_valid"]).astype(bool))
            detected += frame.corners is not None
            out = est.update(frame)
            gt_pos, gt_R = w.sensing.deck_in_body()
            for name, e in out.items():
                if e.valid:
                    d_eul = np.degrees(np.asarray(e.euler) - euler_from_matrix(gt_R))
                    errors[name].append(np.concatenate([np.asarray(e.position) - gt_pos, d_eul]))
    finally:
        w.close()
    return frames, detected, {k: np.abs(np.array(v)) for k, v in errors.items()}


def test_tag_detected_in_at_least_95_percent_of_hover_frames(hover_run):
    frames, detected, _ = hover_run
    assert detected / frames >= 0.95


def test_shipped_calibration_stays_valid_for_the_realistic_camera(hover_run):
    frames, _, errors = hover_run
    for name, err in errors.items():
        assert len(err) >= 0.95 * frames, name
        mae = err.mean(axis=0)
        assert np.all(mae[:3] < 0.006), (name, mae)  # a few mm, as with the ideal camera
        assert np.all(mae[3:] < 1.5), (name, mae)  # degrees


def test_static_deck_frames_differ_only_by_noise(make_world):
    """Nothing moves: two frames differ by the sensor noise (zero mean, a few DN), not by content."""
    w = make_world(WorldConfig(camera=REALISTIC))
    w.reset(StaticProfile(), horizon_s=1.0, altitude=1.0)
    rng = np.random.default_rng(4)
    w.reset_random(rng)
    a = w.sensing.read_sensors(rng, ("camera",))["image"].astype(float)
    b = w.sensing.read_sensors(rng, ("camera",))["image"].astype(float)
    d = a - b
    assert abs(d.mean()) < 0.5 and 0.5 < d.std() < 12
