"""The projected tag camera (ProjectedTagCamera): the exact projection against TagDetector on rendered
frames, occlusion / out-of-view / depth-range failures with reasons, determinism, the contract."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core import detector_model as dm
from ihrcf_env.core.detector_model import DetectorModel
from ihrcf_env.core.estimators import TagDetector
from ihrcf_env.core.frames import matrix_from_euler, quat_from_matrix
from ihrcf_env.core.profiles import StaticProfile, paper_profile
from ihrcf_env.sim.sensors import BodyState, Sensor
from ihrcf_env.sim.sensors.base import TAG_CAMERA
from ihrcf_env.sim.sensors.tag_camera import REASON_DEPTH, REASON_OCCLUDED, ProjectedTagCamera
from ihrcf_env.sim.world import World

MODEL = DetectorModel.load()


def make(world: World, camera: CameraConfig | None = None) -> ProjectedTagCamera:
    cam = camera if camera is not None else world.config.camera
    assert cam is not None
    return ProjectedTagCamera(
        world.client, cam, world.config.rig, world.deck, world.config.deck.tag_size, MODEL
    )


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    w = World(WorldConfig())
    w.reset(StaticProfile(), horizon_s=2.0, altitude=1.0)
    yield w
    w.close()


def place(
    w: World, offset: tuple[float, float], altitude: float, rpy: tuple[float, float, float]
) -> BodyState:
    """Put the drone at ``altitude`` m above the deck origin, shifted by ``offset`` (world, m),
    attitude ``rpy`` (rad), at rest; the deck at its home pose tilted by 0.1 rad roll."""
    home = np.array([0.0, 0.0, w.config.stewart.home_height])
    R_wd = matrix_from_euler(0.1, -0.05, 0.0)
    half = w.config.deck.thickness / 2
    p.resetBasePositionAndOrientation(
        w.deck.body,
        (home - R_wd[:, 2] * half).tolist(),
        quat_from_matrix(R_wd).tolist(),
        physicsClientId=w.client,
    )
    w.deck.update_visuals()
    deck_pos, _ = w.deck.pose()
    R = matrix_from_euler(*rpy)
    pos = deck_pos + np.array([offset[0], offset[1], altitude])
    p.resetBasePositionAndOrientation(
        w.quad.body, pos.tolist(), quat_from_matrix(R).tolist(), physicsClientId=w.client
    )
    return BodyState(0.0, pos, R, quat_from_matrix(R), np.zeros(3), np.zeros(3), np.zeros(3))


POSES = [
    ((0.0, 0.0), 1.0, (0.0, 0.0, 0.3)),
    ((0.2, -0.1), 1.6, (0.05, -0.1, 2.0)),
    ((-0.3, 0.25), 2.4, (-0.1, 0.05, -1.2)),
    ((0.05, 0.1), 0.7, (0.08, 0.02, 0.9)),
]


def test_projection_matches_tag_detector(world: World) -> None:
    """Corner order and sub-pixel convention: the rendered detector's corners sit on the exact
    projection within its noise, with no common offset."""
    assert world.camera is not None
    cam = make(world)
    detector = TagDetector()
    errors = []
    for offset, altitude, rpy in POSES:
        state = place(world, offset, altitude, rpy)
        found = detector.detect(world.camera.render(state.position, state.rotation))
        f, reason = cam.features(state)
        assert found is not None and f is not None, reason
        err = found - f.corners
        assert np.abs(err).max() < 1.2, err  # the right corner, in the right order
        errors.append(err)
    e = np.array(errors).reshape(-1, 2)
    assert np.abs(e.mean(axis=0)).max() < 0.15  # no half-pixel or principal-point offset
    assert math.sqrt(float((e**2).mean())) < 0.6


def test_projection_with_lens_distortion(make_world) -> None:
    cfg = CameraConfig(distortion=(-0.05, 0.01))
    w = make_world(WorldConfig(camera=cfg))
    w.reset(StaticProfile(), horizon_s=2.0, altitude=1.0)
    assert w.camera is not None
    cam = make(w)
    state = place(w, (0.25, 0.2), 1.3, (0.05, 0.0, 0.7))
    found = TagDetector().detect(w.camera.render(state.position, state.rotation))
    f, _ = cam.features(state)
    assert found is not None and f is not None
    assert np.abs(found - f.corners).max() < 1.2


def test_reading_contract_and_out_of_view(world: World) -> None:
    cam = make(world)
    assert isinstance(cam, Sensor) and cam.name == TAG_CAMERA
    rng = np.random.default_rng(0)
    cam.reset(rng)
    r = cam.read(place(world, (0.0, 0.0), 1.0, (0.0, 0.0, 0.3)), 0.05, rng)
    assert bool(r["tag_detected"]) and str(r["tag_reason"]) == ""
    assert r["tag_corners"].shape == (4, 2) and r["tag_corners"].dtype == np.float64
    r = cam.read(place(world, (1.5, 0.0), 1.0, (0.0, 0.0, 0.0)), 0.05, rng)  # tag beside the image
    assert not bool(r["tag_detected"]) and str(r["tag_reason"]) == dm.REASON_OUTSIDE
    assert np.array_equal(r["tag_corners"], np.zeros((4, 2)))
    r = cam.read(place(world, (0.55, 0.0), 1.0, (0.0, 0.0, 0.0)), 0.05, rng)  # half out
    assert not bool(r["tag_detected"]) and str(r["tag_reason"]) == dm.REASON_BORDER
    # looking up: the deck behind the camera
    r = cam.read(place(world, (0.0, 0.0), 1.0, (math.pi, 0.0, 0.0)), 0.05, rng)
    assert not bool(r["tag_detected"]) and str(r["tag_reason"]) == REASON_DEPTH
    # beyond the far plane
    near_sighted = make(world, replace(CameraConfig(), far=0.8))
    r = near_sighted.read(place(world, (0.0, 0.0), 1.0, (0.0, 0.0, 0.0)), 0.05, rng)
    assert not bool(r["tag_detected"]) and str(r["tag_reason"]) == REASON_DEPTH


def test_occlusion(world: World) -> None:
    cam = make(world)
    rng = np.random.default_rng(1)
    state = place(world, (0.0, 0.0), 1.2, (0.0, 0.0, 0.4))
    assert bool(cam.read(state, 0.05, rng)["tag_detected"])
    deck_pos, R_wd = world.deck.pose()
    eye = state.position + state.rotation @ np.asarray(world.config.rig.camera_position)
    corner = deck_pos + R_wd @ np.array([0.2, 0.2, 0.0])
    cid = world.client
    box = p.createMultiBody(
        baseMass=0,
        baseCollisionShapeIndex=p.createCollisionShape(
            p.GEOM_BOX, halfExtents=[0.03] * 3, physicsClientId=cid
        ),
        basePosition=((eye + corner) / 2).tolist(),  # halfway along the line of sight to a corner
        physicsClientId=cid,
    )
    try:
        assert cam.occluded(state)
        r = cam.read(state, 0.05, rng)
        assert not bool(r["tag_detected"]) and str(r["tag_reason"]) == REASON_OCCLUDED
    finally:
        p.removeBody(box, physicsClientId=cid)
    assert not cam.occluded(state)


@pytest.mark.parametrize("quality", ["ideal", "realistic"])
def test_bitwise_determinism_per_seed(make_world, quality: str) -> None:
    def run(seed: int) -> list[np.ndarray]:
        w = make_world(WorldConfig(camera=CameraConfig(quality=quality)))
        w.reset(paper_profile(), horizon_s=3.0, altitude=1.2, offset_xy=(0.1, -0.05), yaw=0.4)
        rng = np.random.default_rng(seed)
        cam = make(w)
        cam.reset(rng)
        w.set_velocity_setpoint(np.array([0.2, -0.1, 0.0, 0.3]))
        out = []
        for _ in range(15):
            w.step()
            r = cam.read(w.sensing.body_state(), 0.05, rng)
            out.append(np.concatenate([r["tag_corners"].ravel(), [float(r["tag_detected"])]]))
        return out

    a, b, c = run(3), run(3), run(4)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_realistic_episode_is_the_rendered_cameras(make_world) -> None:
    """Same generator state: the projected camera draws the episode (light, exposure, gain) the
    rendered camera draws; a given episode is used as is."""
    w = make_world(WorldConfig(camera=CameraConfig(quality="realistic")))
    w.reset(StaticProfile(), horizon_s=2.0, altitude=1.0)
    assert w.camera is not None
    w.camera.reset(np.random.default_rng(5))
    cam = make(w)
    cam.reset(np.random.default_rng(5))
    assert cam.episode == w.camera.episode
    other = make(w)
    other.reset(np.random.default_rng(6), episode=w.camera.episode)
    assert other.episode is w.camera.episode
    f, _ = cam.features(place(w, (0.0, 0.0), 1.0, (0.0, 0.0, 0.0)))
    assert f is not None and np.all(f.noise_ratio > 0)


def test_bad_arguments(world: World) -> None:
    cfg = world.config
    with pytest.raises(TypeError, match="model"):
        ProjectedTagCamera(world.client, CameraConfig(), cfg.rig, world.deck, 0.4, "model.json")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="camera"):
        ProjectedTagCamera(world.client, None, cfg.rig, world.deck, 0.4, MODEL)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="tag_size"):
        ProjectedTagCamera(world.client, CameraConfig(), cfg.rig, world.deck, -0.4, MODEL)
