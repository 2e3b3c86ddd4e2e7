"""The projected tag camera's reading (ihrcf_env.fast.tag_camera) against ClosedFormTagCamera.read,
float64: projection, depth range, detector model and occlusion."""

from __future__ import annotations

import copy

import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.collision import drone_boxes
from ihrcf_env.core.detector_model import DetectorModel
from ihrcf_env.core.rig import SensorRig
from ihrcf_env.fast.rays import Scene
from ihrcf_env.fast.tag_camera import STATUS_OCCLUDED, Imaging, imaging_of, tag_camera_setup, tag_read
from ihrcf_env.sim.sensors.base import tag_status_code
from ihrcf_env.sim.sensors.closed_form_camera import ClosedFormTagCamera
from ihrcf_env.sim.sensors.corner_model import CornerTracks
from ihrcf_env.sim.sensors.imaging import draw_episode
from ihrcf_env.sim.sensors.rays import RayScene
from ihrcf_env.sim.sensors.tag_camera import RAY_MARGIN_M, REASON_OCCLUDED

from .fast_helpers import Counted, rel_err, rotations

CFG = WorldConfig()
RAY_SCENE = RayScene.of(CFG.deck.size, CFG.deck.thickness, CFG.stewart.base_radius, CFG.stewart.base_height)
SCENE = Scene(
    jnp.asarray(RAY_SCENE.deck_half_extents),
    jnp.asarray(RAY_SCENE.base_radius),
    jnp.asarray(RAY_SCENE.base_height),
)
TAG = 0.4
MODEL = DetectorModel.load()


def test_constants_are_the_simulators() -> None:
    assert STATUS_OCCLUDED == tag_status_code(REASON_OCCLUDED)


#: A base reaching above the lower decks (their tag behind its top face): occluded frames.
TALL = RayScene(RAY_SCENE.deck_half_extents, 0.5, 0.9)


@pytest.mark.parametrize(("tall", "quality"), [(False, "ideal"), (True, "ideal"), (False, "realistic")])
def test_tag_read_matches_closed_form_camera(tall: bool, quality: str) -> None:
    camera = CameraConfig(distortion=(-0.05, 0.01), quality=quality)
    rig = SensorRig()
    ray_scene = TALL if tall else RAY_SCENE
    scene = Scene(
        *(jnp.asarray(v) for v in (ray_scene.deck_half_extents, ray_scene.base_radius, ray_scene.base_height))
    )
    ref = ClosedFormTagCamera(camera, rig, ray_scene, TAG, MODEL)
    setup = tag_camera_setup(camera, rig, TAG, MODEL, scene, drone_boxes(), RAY_MARGIN_M)
    rng = np.random.default_rng(0)
    n = 600
    R = rotations(rng, n, 0.5)
    dR = rotations(rng, n, 0.15)
    dp = np.column_stack([rng.uniform(-0.2, 0.2, (n, 2)), rng.uniform(0.6, 1.2, n)])
    height = np.concatenate([rng.uniform(0.05, 0.4, n // 4), rng.uniform(0.3, 6.0, n - n // 4)])
    p = dp + np.column_stack([rng.uniform(-1.5, 1.5, (n, 2)), height])
    p[:20] = dp[:20] + np.column_stack([rng.uniform(1.0, 2.5, (20, 2)), rng.uniform(-0.5, 0.2, 20)])
    track = CornerTracks(n)
    track.reset([np.random.default_rng([1, i]) for i in range(n)])
    gens = [np.random.default_rng([2, i]) for i in range(n)]
    ahead = copy.deepcopy(gens)
    normals = np.stack([g.standard_normal((4, 2)) for g in ahead])
    uniforms = np.array([g.random() for g in ahead])
    if quality == "realistic":
        vel = rng.normal(0.0, 1.0, (n, 3))
        omega = rng.normal(0.0, 1.5, (n, 3))
        episodes = [draw_episode(camera.imaging, np.random.default_rng([3, i])) for i in range(n)]
        want = ref.read(p, R, dp, dR, track, gens, vel, omega, episodes)
        im = [imaging_of(e, vel[i], omega[i]) for i, e in enumerate(episodes)]
        ims = Imaging(*(np.stack([np.asarray(getattr(x, f)) for x in im]) for f in Imaging._fields))
        fn = Counted(lambda *a: tag_read(setup, *a[:8], imaging=a[8]))
        args: tuple = (p, R, dp, dR, normals, uniforms, track.omega, track.phase, ims)
    else:
        want = ref.read(p, R, dp, dR, track, gens)
        fn = Counted(lambda *a: tag_read(setup, *a))
        args = (p, R, dp, dR, normals, uniforms, track.omega, track.phase)
    got = fn(*args)
    assert np.array_equal(np.asarray(got.status), want["tag_status"])
    assert np.array_equal(np.asarray(got.detected), want["tag_detected"])
    counts = np.bincount(want["tag_status"], minlength=12)
    assert counts[0] > 50 and counts[2] > 50 and counts[4] > 10 and counts[9] > 5, counts
    assert (counts[10] > 10) == tall, counts
    assert rel_err(got.corners, want["tag_corners"]) < 1e-9
    fn(*args)
    assert fn.traces == 1
