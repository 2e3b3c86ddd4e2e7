"""Rendering and detecting only the tag's window: off-axis windows equal the crop of the full frame
(ideal, lens distortion, realistic; up to TinyRenderer's rare texel-edge flips), windowed detection
equals full-frame detection, the tag-only scene renders the world's pixels, and WindowedTagCamera
gives the corners of rendering the full frame and detecting in it."""

import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pybullet as p
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.estimators import TagDetector
from ihrcf_env.core.profiles import paper_profile
from ihrcf_env.sim.sensors import DownCamera
from ihrcf_env.sim.sensors.base import TAG_CAMERA, BodyState
from ihrcf_env.sim.sensors.camera import check_window, tiny_render, window_projection
from ihrcf_env.sim.sensors.tag_window import TagScene, WindowedTagCamera
from ihrcf_env.sim.world import World

W = H = 512
DISTORTION = (-0.08, 0.02)
#: windows touching every border, single pixels, thin strips, the whole frame
EDGE_WINDOWS = [(0, 0, W, H), (0, 0, 1, 1), (W - 1, H - 1, 1, 1), (0, 200, 40, H - 200), (480, 0, 32, 100)]
#: TinyRenderer rounds a window's barycentric coordinates differently from the full frame's: a
#: texture lookup within ~1e-5 texel of a texel edge can land on the other side (measured: 4 of
#: 4.3 million tag pixels). Allowed fraction of differing pixels; a real error (a shifted or
#: mis-scaled window) changes thousands.
FLIPS = 2e-5


def assert_same_pixels(a: np.ndarray, b: np.ndarray, allowed: float = FLIPS) -> None:
    assert a.shape == b.shape
    differing = int(np.any(a != b, axis=-1).sum()) if a.ndim == 3 else int((a != b).sum())
    assert differing <= allowed * a.shape[0] * a.shape[1], differing


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    w = World(WorldConfig())
    try:
        w.reset(paper_profile(), horizon_s=30.0, altitude=1.0)
        for _ in range(5):
            w.step()
        w.deck.update_visuals()
        yield w
    finally:
        w.close()


def random_windows(rng: np.random.Generator, n: int) -> list[tuple[int, int, int, int]]:
    out = []
    for _ in range(n):
        w, h = int(rng.integers(1, W + 1)), int(rng.integers(1, H + 1))
        out.append((int(rng.integers(0, W - w + 1)), int(rng.integers(0, H - h + 1)), w, h))
    return out + EDGE_WINDOWS


def moving(state: BodyState, velocity: tuple[float, ...], omega: tuple[float, ...]) -> BodyState:
    return replace(state, velocity=np.array(velocity, float), angular_velocity=np.array(omega, float))


def pose_with_tag_at(world: World, cam: DownCamera, rng: np.random.Generator, uv: np.ndarray) -> BodyState:
    """A drone state 0.55-2.5 m above the deck, tilted and yawed at random, whose camera sees the
    deck centre at pixel ``uv``; the quadrotor body is moved there too."""
    deck_pos, _ = world.deck.pose()
    rot = Rotation.from_euler(
        "xyz", [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi)]
    )
    R = rot.as_matrix()
    offset, R_wc = cam.pose(np.zeros(3), R)
    ray = R_wc @ (np.linalg.inv(cam.config.intrinsics) @ np.array([uv[0], uv[1], 1.0]))
    ray /= np.linalg.norm(ray)
    eye = deck_pos - ray * (rng.uniform(0.55, 2.5) / max(-ray[2], 0.2))
    pos = eye - offset
    quat = rot.as_quat()
    p.resetBasePositionAndOrientation(
        world.quad.body, pos.tolist(), quat.tolist(), physicsClientId=world.client
    )
    return BodyState(
        time=world.time,
        position=pos,
        rotation=R,
        quaternion=quat,
        velocity=rng.normal(0.0, 0.4, 3),
        angular_velocity=rng.normal(0.0, 0.4, 3),
        acceleration=np.zeros(3),
    )


# -- the off-axis projection -----------------------------------------------------------------------


def test_window_render_is_pixel_identical_to_the_crop(world: World):
    cam = world.camera
    assert cam is not None
    c = cam.config
    rng = np.random.default_rng(0)
    for _ in range(2):
        state = pose_with_tag_at(world, cam, rng, rng.uniform(100, 412, 2))
        eye, R_wc = cam.pose(state.position, state.rotation)
        view = cam._view(eye, R_wc)
        rgb, _, seg = tiny_render(world.client, c, view, cam._proj, None, True)
        for win in random_windows(rng, 6):
            x0, y0, w, h = win
            proj = window_projection(cam._proj, W, H, win)
            rgb_w, _, seg_w = tiny_render(world.client, c, view, proj, None, True, size=(w, h))
            assert_same_pixels(rgb_w, rgb[y0 : y0 + h, x0 : x0 + w])
            assert seg_w is not None and seg is not None
            assert_same_pixels(seg_w, seg[y0 : y0 + h, x0 : x0 + w])
            img = cam.render_window(state.position, state.rotation, win)
            assert_same_pixels(img, rgb[y0 : y0 + h, x0 : x0 + w])
    # the whole frame as a window is the full projection itself
    assert window_projection(cam._proj, W, H, (0, 0, W, H)) == pytest.approx(cam._proj, abs=0.0)


def test_distorted_window_is_the_crop_of_the_distorted_image(world: World):
    cam = DownCamera(world.client, CameraConfig(distortion=DISTORTION), world.config.rig)
    rng = np.random.default_rng(1)
    state = pose_with_tag_at(world, cam, rng, np.array([300.0, 200.0]))
    full = cam.render(state.position, state.rotation)
    for win in random_windows(rng, 6):
        x0, y0, w, h = win
        src = cam._source_region(win)
        if win != (0, 0, W, H) and w * h > 10_000:
            assert src != win  # barrel distortion: the window samples a different pinhole region
        img = cam.render_window(state.position, state.rotation, win)
        assert_same_pixels(img, full[y0 : y0 + h, x0 : x0 + w])


@pytest.mark.parametrize("distortion", [(0.0, 0.0), DISTORTION])
def test_realistic_window_is_the_crop_of_the_realistic_frame(world: World, distortion):
    """The same bytes (background (sea) included, motion blur up to an 11x11 kernel) but for the
    render's texel-edge flips, spread by the blur; the random stream is drawn exactly as by the
    full read."""
    cam = DownCamera(world.client, CameraConfig(quality="realistic", distortion=distortion), world.config.rig)
    cam.reset(np.random.default_rng(3))
    rng = np.random.default_rng(4)
    base = pose_with_tag_at(world, cam, rng, np.array([256.0, 255.0]))
    for velocity, omega in [
        ((0, 0, 0), (0, 0, 0)),
        ((0.3, -0.2, 0.1), (0.2, 0.5, 0.1)),
        ((2, 1, 0), (1, 2, 0.3)),
    ]:
        state = moving(base, velocity, omega)
        windows = random_windows(rng, 3)
        for k, win in enumerate(windows):
            r_full, r_win = np.random.default_rng(k), np.random.default_rng(k)
            full = cam.read(state, 0.05, r_full)["image"]
            x0, y0, w, h = win
            img = cam.read_window(state, win, r_win)
            assert_same_pixels(img, full[y0 : y0 + h, x0 : x0 + w], allowed=121 * FLIPS)
            assert r_full.random() == r_win.random()


def test_realistic_window_with_a_long_blur_streak_is_within_one_dn(world: World):
    """A streak longer than 8 px: OpenCV convolves a >= 13x13 kernel by DFT, which depends on the
    image size; the window then differs from the crop by 1 DN on a few pixels (the bound)."""
    cam = DownCamera(world.client, CameraConfig(quality="realistic"), world.config.rig)
    cam.reset(np.random.default_rng(5))
    assert cam.episode is not None
    rng = np.random.default_rng(6)
    spin = 15.0 / (cam.config.intrinsics[0, 0] * cam.episode.exposure_s)  # rad/s: a ~15 px streak
    state = moving(
        pose_with_tag_at(world, cam, rng, np.array([256.0, 255.0])), (0, 0, 0), (0.6 * spin, 0.8 * spin, 0)
    )
    differing = total = 0
    for k, win in enumerate(random_windows(rng, 4)):
        full = cam.read(state, 0.05, np.random.default_rng(k))["image"]
        x0, y0, w, h = win
        img = cam.read_window(state, win, np.random.default_rng(k))
        diff = np.abs(img.astype(int) - full[y0 : y0 + h, x0 : x0 + w]).max(axis=2)
        assert (diff > 1).sum() <= 121 * FLIPS * w * h  # beyond 1 DN: only the render's flips
        differing += int((diff > 0).sum())
        total += w * h
    assert cam._blur_margin > 6  # the kernel was at least 13x13
    assert differing <= 1e-3 * total


def test_window_is_validated(world: World):
    cam = world.camera
    assert cam is not None
    s = world.sensing.body_state()
    with pytest.raises(ValueError, match="window"):
        cam.render_window(s.position, s.rotation, (500, 0, 20, 10))
    with pytest.raises(ValueError, match="window"):
        cam.render_window(s.position, s.rotation, (0, 0, 0, 10))
    with pytest.raises(TypeError, match="window"):
        cam.render_window(s.position, s.rotation, (0, 0, 10))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="window"):
        check_window((0.0, 0, 10, 10), W, H)


# -- the tag-only scene ----------------------------------------------------------------------------


def hover_state(world: World, cam: DownCamera, rng: np.random.Generator, altitude: float) -> BodyState:
    """Nearly level, nearly unyawed, the tag near the image centre: the window fits in its image."""
    deck_pos, R_deck = world.deck.pose()
    yaw = math.atan2(R_deck[1, 0], R_deck[0, 0]) + rng.uniform(-0.05, 0.05)
    rot = Rotation.from_euler("xyz", [rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05), yaw])
    pos = deck_pos + np.array([*rng.uniform(-0.05, 0.05, 2), altitude])
    quat = rot.as_quat()
    p.resetBasePositionAndOrientation(
        world.quad.body, pos.tolist(), quat.tolist(), physicsClientId=world.client
    )
    return replace(world.sensing.body_state(), position=pos, rotation=rot.as_matrix(), quaternion=quat)


@pytest.mark.parametrize("quality", ["ideal", "realistic"])
def test_tag_scene_renders_the_world_pixels(world: World, quality):
    cam = DownCamera(world.client, CameraConfig(quality=quality), world.config.rig)
    cam.reset(np.random.default_rng(14))
    tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
    scene = tags.scene
    assert isinstance(scene, TagScene)
    rng = np.random.default_rng(15)
    used = 0
    for altitude in (0.8, 1.0, 1.4, 2.0):
        state = moving(hover_state(world, cam, rng, altitude), (0.2, 0.1, 0.0), (0.1, -0.2, 0.0))
        window, inside = tags.tag_window(state)
        assert window is not None and inside and window != (0, 0, W, H)
        scene.prepare(state)
        inner = scene.inner(window)
        if inner is not None:
            used += 1
            x0, y0, w, h = window
            assert (
                inner[0] >= x0
                and inner[1] >= y0
                and inner[0] + inner[2] <= x0 + w
                and inner[1] + inner[3] <= y0 + h
            )
        with_scene = cam.read_window(state, window, np.random.default_rng(1), scene)
        world_only = cam.read_window(state, window, np.random.default_rng(1))
        assert_same_pixels(with_scene, world_only, allowed=121 * FLIPS)
    assert used >= 3
    tags.close()


def test_tag_scene_steps_aside_for_what_it_does_not_hold(world: World):
    """A body in front of the tag, a visual of unknown extent, a camera below the tag's plane: the
    scene offers nothing (or only what the body leaves free) and the window is the world's."""
    cam = world.camera
    assert cam is not None
    tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
    scene = tags.scene
    assert scene is not None
    state = hover_state(world, cam, np.random.default_rng(16), 1.0)
    window, _ = tags.tag_window(state)
    assert window is not None
    scene.prepare(state)
    assert scene.inner(window) is not None
    cid = world.client
    deck_pos, _ = world.deck.pose()
    box = p.createVisualShape(
        p.GEOM_BOX, halfExtents=[0.03, 0.03, 0.01], rgbaColor=[1, 0, 0, 1], physicsClientId=cid
    )
    body = p.createMultiBody(
        baseVisualShapeIndex=box, basePosition=(deck_pos + [0, 0, 0.3]).tolist(), physicsClientId=cid
    )
    try:
        scene.prepare(state)
        assert scene.inner(window) is None  # the box sits in the middle of the window
        with_scene = cam.render_window(state.position, state.rotation, window, scene)
        world_only = cam.render_window(state.position, state.rotation, window)
        assert np.array_equal(with_scene, world_only)
        assert np.any(
            np.all(with_scene == with_scene[with_scene.shape[0] // 2, with_scene.shape[1] // 2], axis=2)
        )
    finally:
        p.removeBody(body, physicsClientId=cid)
    mesh = p.createVisualShape(
        p.GEOM_MESH,
        fileName=str(p.getVisualShapeData(world.deck.tag_body, physicsClientId=cid)[0][4].decode()),
        physicsClientId=cid,
    )
    body = p.createMultiBody(baseVisualShapeIndex=mesh, basePosition=[5, 5, 0], physicsClientId=cid)
    try:
        scene.prepare(state)
        assert scene.inner(window) is None  # a mesh of unknown extent somewhere in the world
    finally:
        p.removeBody(body, physicsClientId=cid)
    scene.prepare(state)
    assert scene.inner(window) is not None
    below = replace(state, position=deck_pos - np.array([0.0, 0.0, 1.0]))
    scene.prepare(below)
    assert scene.inner(window) is None
    client = scene.client
    tags.close()
    assert not p.getConnectionInfo(physicsClientId=client)["isConnected"]


# -- windowed detection ----------------------------------------------------------------------------


def test_detector_in_a_window_returns_the_full_frame_corners(world: World):
    cam = world.camera
    assert cam is not None
    tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
    detector = TagDetector(0)
    rng = np.random.default_rng(7)
    compared = 0
    for _ in range(6):
        state = pose_with_tag_at(world, cam, rng, rng.uniform(150, 362, 2))
        full = cam.render(state.position, state.rotation)
        window, inside = tags.tag_window(state)
        assert window is not None and inside and window != (0, 0, W, H)
        x0, y0, w, h = window
        expected = detector.detect(full)
        got = detector.detect(np.ascontiguousarray(full[y0 : y0 + h, x0 : x0 + w]), (x0, y0), (W, H))
        assert (expected is None) == (got is None)
        if expected is not None and got is not None:
            assert np.abs(got - expected).max() < 1e-3
            compared += 1
    assert compared >= 4
    # the full frame as a window is the full-frame detection
    assert np.array_equal(detector.detect(full, (0, 0), (W, H)), detector.detect(full))  # type: ignore[arg-type]


def test_detector_window_arguments_are_checked():
    detector = TagDetector(0)
    img = np.zeros((20, 30), np.uint8)
    with pytest.raises(ValueError, match="together"):
        detector.detect(img, origin=(0, 0))
    with pytest.raises(ValueError, match="fit"):
        detector.detect(img, origin=(500, 0), full_size=(512, 512))
    with pytest.raises(TypeError, match="origin"):
        detector.detect(img, origin=(0.5, 0), full_size=(512, 512))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="full_size"):
        detector.detect(img, origin=(0, 0), full_size=(0, 512))


# -- the windowed tag camera -----------------------------------------------------------------------


def compare_with_full(world: World, cam: DownCamera, n: int, seed: int) -> dict[str, float]:
    """Read ``n`` random poses with a WindowedTagCamera and with the full read + detect; the tag
    is anywhere in the image (half the poses put its centre within 40 px of the border or off it)."""
    tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
    detector = TagDetector(0)
    rng = np.random.default_rng(seed)
    stats = {"both": 0, "neither": 0, "windowed": 0, "whole frame": 0, "skipped": 0, "max_px": 0.0}
    for k in range(n):
        uv = rng.uniform(-40, W + 40, 2) if k % 2 else rng.uniform(100, 412, 2)
        state = pose_with_tag_at(world, cam, rng, uv)
        r_full, r_win = np.random.default_rng(k), np.random.default_rng(k)
        world.deck.update_visuals()
        expected = detector.detect(cam.read(state, 0.05, r_full)["image"])
        reading = tags.read(state, 0.05, r_win)
        assert r_full.random() == r_win.random()  # the same draws as the full camera
        got = reading["tag_corners"] if bool(reading["tag_detected"]) else None
        assert (expected is None) == (got is None), (k, expected, got, tags.window)
        key = (
            "skipped" if tags.window is None else "whole frame" if tags.window == (0, 0, W, H) else "windowed"
        )
        stats[key] += 1
        if expected is None or got is None:
            stats["neither"] += 1
            assert str(reading["tag_reason"]) != ""
        else:
            stats["both"] += 1
            stats["max_px"] = max(stats["max_px"], float(np.abs(got - expected).max()))
    return stats


def test_windowed_tag_camera_matches_full_render_and_detect(world: World):
    cam = world.camera
    assert cam is not None
    stats = compare_with_full(world, cam, 40, seed=8)
    assert stats["max_px"] < 0.05  # the contract (measured: < 1e-4 px)
    assert stats["both"] >= 15 and stats["neither"] >= 3
    assert stats["windowed"] >= 15 and stats["whole frame"] >= 3


def test_windowed_tag_camera_matches_with_distortion_and_realistic_quality(world: World):
    cam = DownCamera(world.client, CameraConfig(quality="realistic", distortion=DISTORTION), world.config.rig)
    cam.reset(np.random.default_rng(9))
    stats = compare_with_full(world, cam, 16, seed=10)
    assert stats["max_px"] < 0.05
    assert stats["both"] >= 6 and stats["windowed"] >= 6


def test_windowed_tag_camera_is_bitwise_deterministic(world: World):
    def run() -> list[np.ndarray]:
        cam = DownCamera(world.client, CameraConfig(quality="realistic"), world.config.rig)
        tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
        rng = np.random.default_rng(11)
        tags.reset(rng)
        poses = np.random.default_rng(12)
        out = []
        for _ in range(4):
            state = pose_with_tag_at(world, cam, poses, poses.uniform(120, 392, 2))
            out.append(tags.read(state, 0.05, rng)["tag_corners"])
        out.append(np.array([rng.random()]))
        return out

    a, b = run(), run()
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert any(np.any(x) for x in a[:-1])


def test_tag_outside_the_image_is_not_rendered(world: World, monkeypatch):
    cam = DownCamera(world.client, CameraConfig(quality="realistic"), world.config.rig)
    tags = WindowedTagCamera(cam, world.deck, 0.4, 0)
    assert tags.name == TAG_CAMERA
    deck_pos, _ = world.deck.pose()
    state = replace(world.sensing.body_state(), position=deck_pos + np.array([3.0, 0.0, 1.0]))

    def no_render(*args, **kwargs):
        raise AssertionError("rendered a frame with the tag out of view")

    monkeypatch.setattr(cam, "_render_region", no_render)
    r_full, r_win = np.random.default_rng(13), np.random.default_rng(13)
    reading = tags.read(state, 0.05, r_win)
    assert not bool(reading["tag_detected"]) and str(reading["tag_reason"]) == "tag outside the image"
    assert np.array_equal(reading["tag_corners"], np.zeros((4, 2)))
    assert tags.window is None
    monkeypatch.undo()
    cam2 = DownCamera(world.client, CameraConfig(quality="realistic"), world.config.rig)
    cam2.read(state, 0.05, r_full)  # the full camera's draws: episode + one frame
    assert r_full.random() == r_win.random()


def test_windowed_tag_camera_arguments_are_checked(world: World):
    cam = world.camera
    assert cam is not None
    with pytest.raises(TypeError, match="camera"):
        WindowedTagCamera(object(), world.deck, 0.4, 0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="deck"):
        WindowedTagCamera(cam, object(), 0.4, 0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="margin"):
        WindowedTagCamera(cam, world.deck, 0.4, 0, margin=-1)
    with pytest.raises(ValueError, match="tag_size"):
        WindowedTagCamera(cam, world.deck, -0.4, 0)
