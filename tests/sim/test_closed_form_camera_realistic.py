"""The closed-form projected camera's realistic quality (noise ratio, motion blur) against the scalar
read with Bullet's rays, and row by row against itself: rows do not depend on the batch."""

from __future__ import annotations

import copy
from collections.abc import Iterator
from dataclasses import replace

import numpy as np
import pybullet as p
import pytest
from test_closed_form_camera import look_at, place, scene_of

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.detector_model import CornerTrack
from ihrcf_env.core.frames import matrix_from_quat
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.sensors import BodyState
from ihrcf_env.sim.sensors.base import TAG_CAMERA
from ihrcf_env.sim.sensors.closed_form_camera import ClosedFormTagCamera
from ihrcf_env.sim.sensors.tag_camera import ProjectedTagCamera
from ihrcf_env.sim.world import World

N = 40


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    camera = replace(CameraConfig(), quality="realistic")
    w = World(WorldConfig(camera=camera, camera_model="projected", camera_output="corners"))
    w.reset(StaticProfile(), horizon_s=2.0, altitude=1.0)
    yield w
    w.close()


def _cases(w: World, seed: int) -> list[tuple[BodyState, np.ndarray, np.ndarray, tuple]]:
    """N views from above (the tag in view or near the border) with the drone moving and turning:
    (state, deck position, deck rotation as the scalar camera sees them, the bodies' poses)."""
    rng = np.random.default_rng(seed)
    off = np.asarray(w.config.rig.camera_position)
    home = w.config.stewart.home_height
    out = []
    for i in range(N):
        rpy = rng.uniform(-0.2, 0.2, 3)
        deck_pos = np.array([*rng.uniform(-0.2, 0.2, 2), home + rng.uniform(-0.1, 0.1)])
        deck_q = np.asarray(p.getQuaternionFromEuler(rpy.tolist()))
        Rd = matrix_from_quat(deck_q)
        target = deck_pos + Rd @ np.array([*rng.uniform(-0.3, 0.3, 2), 0.0])
        eye = deck_pos + Rd @ np.array([*rng.uniform(-0.5, 0.5, 2), rng.uniform(0.4, 3.0)])
        pos, q = look_at(eye, target, 0.7 * i, off)
        body = deck_pos - Rd[:, 2] * w.config.deck.thickness / 2
        state, dp, dR = place(w, pos, q, body, deck_q)
        state = replace(state, velocity=rng.normal(0, 1.5, 3), angular_velocity=rng.normal(0, 1.0, 3))
        out.append((state, dp, dR, (pos, q, body, deck_q)))
    return out


def _closed_form(w: World, cam: ProjectedTagCamera) -> ClosedFormTagCamera:
    return ClosedFormTagCamera(cam.camera, w.config.rig, scene_of(w), w.config.deck.tag_size, cam.model)


def test_realistic_rows_follow_the_scalar_read(world: World) -> None:
    cam = world.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera) and cam.quality == "realistic"
    bcam = _closed_form(world, cam)
    cases = _cases(world, 3)
    episodes, tracks, rngs = [], [], []
    for i in range(N):
        cam.reset(np.random.default_rng([7, i]))  # the episode's imaging and its track
        episodes.append(cam.episode)
        tracks.append(copy.deepcopy(cam.track))
        rngs.append(np.random.default_rng([8, i]))
    expected = []
    s_rngs, s_tracks = copy.deepcopy(rngs), copy.deepcopy(tracks)
    for i, (state, _, _, bodies) in enumerate(cases):
        cam.reset(np.random.default_rng(0), episode=episodes[i])  # its imaging (gain) back
        cam.track = s_tracks[i]
        place(world, *bodies)
        expected.append(cam.read(state, 0.05, s_rngs[i]))
    got = bcam.read(
        np.array([c[0].position for c in cases]),
        np.array([c[0].rotation for c in cases]),
        np.array([c[1] for c in cases]),
        np.array([c[2] for c in cases]),
        tracks,
        rngs,
        velocity=np.array([c[0].velocity for c in cases]),
        angular_velocity=np.array([c[0].angular_velocity for c in cases]),
        episodes=episodes,
    )
    detected = 0
    worst = 0.0
    for i, e in enumerate(expected):
        assert got["tag_status"][i] == e["tag_status"], (i, got["tag_reason"][i], e["tag_reason"])
        if e["tag_detected"]:
            detected += 1
            worst = max(worst, float(np.abs(got["tag_corners"][i] - e["tag_corners"]).max()))
    print(f"{detected}/{N} detected; max |closed form - scalar| corner {worst:.3g} px")
    assert detected >= N // 2
    assert worst < 1e-2  # the scene depth is Bullet's to within its 1 mm tolerance (equal here)
    with pytest.raises(ValueError, match="realistic"):  # no velocities, no imaging
        bcam.read(
            cases[0][0].position[None],
            cases[0][0].rotation[None],
            cases[0][1][None],
            cases[0][2][None],
            [CornerTrack()],
            [np.random.default_rng(0)],
        )


def test_realistic_rows_do_not_depend_on_the_batch(world: World) -> None:
    cam = world.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    bcam = _closed_form(world, cam)
    cases = _cases(world, 5)
    episodes = []
    for i in range(N):
        cam.reset(np.random.default_rng([9, i]))
        episodes.append(cam.episode)

    def run(rows: list[int]) -> dict[str, np.ndarray]:
        return bcam.read(
            np.array([cases[i][0].position for i in rows]),
            np.array([cases[i][0].rotation for i in rows]),
            np.array([cases[i][1] for i in rows]),
            np.array([cases[i][2] for i in rows]),
            [CornerTrack(np.random.default_rng([10, i])) for i in rows],
            [np.random.default_rng([11, i]) for i in rows],
            velocity=np.array([cases[i][0].velocity for i in rows]),
            angular_velocity=np.array([cases[i][0].angular_velocity for i in rows]),
            episodes=[episodes[i] for i in rows],
        )

    full = run(list(range(N)))
    for rows in ([0], [N - 1], list(range(1, N, 3))):
        part = run(rows)
        for key in ("tag_corners", "tag_status", "tag_reason"):
            assert np.array_equal(part[key], full[key][rows]), (rows, key)
