"""The closed-form projected tag camera (ihrcf_env.sim.sensors.closed_form_camera) against the scalar
ProjectedTagCamera.read of a World, row by row, over consecutive reads.

Occlusion: the scalar camera asks Bullet, whose convex ray cast stops up to 1 mm off a box's or
the cylinder's surface (tests/sim/test_closed_form_rays.py); the rays stop RAY_MARGIN_M = 2 mm short
of the tag, i.e. 2 mm cos(incidence) off the deck's top face. Poses where the occlusion verdict
changes when every collision surface moves by 1 mm out or in (deck plate, base, drone boxes)
and the model would report the tag are not used (``ambiguous``); the others must agree exactly.
"""

from __future__ import annotations

import copy
from collections.abc import Iterator

import numpy as np
import pybullet as p
import pytest

from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.collision import drone_boxes
from ihrcf_env.core.detector_model import CornerTrack
from ihrcf_env.core.frames import R_BODY_CAM, matrix_from_quat, quat_from_matrix
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.sim.sensors import BodyState
from ihrcf_env.sim.sensors.base import TAG_CAMERA, TAG_STATUS
from ihrcf_env.sim.sensors.closed_form_camera import ClosedFormTagCamera
from ihrcf_env.sim.sensors.corner_model import CornerTracks
from ihrcf_env.sim.sensors.rays import RayScene, _box_entry, cast_rays, to_local
from ihrcf_env.sim.sensors.tag_camera import RAY_MARGIN_M, ProjectedTagCamera
from ihrcf_env.sim.world import World

EPS = 1e-3  # m: Bullet's convex-cast tolerance
READS = 4
KEYS = ("tag_corners", "tag_detected", "tag_reason", "tag_status")


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    w = World(WorldConfig(camera_model="projected", camera_output="corners"))
    w.reset(StaticProfile(), horizon_s=2.0, altitude=1.0)
    yield w
    w.close()


def scene_of(w: World) -> RayScene:
    c = w.config
    return RayScene.of(c.deck.size, c.deck.thickness, c.stewart.base_radius, c.stewart.base_height)


def closed_form(w: World) -> ClosedFormTagCamera:
    cam = w.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    return ClosedFormTagCamera(cam.camera, w.config.rig, scene_of(w), w.config.deck.tag_size, cam.model)


def look_at(eye: np.ndarray, target: np.ndarray, spin: float, rig_offset: np.ndarray):
    """(drone position, quaternion) with the optical axis from ``eye`` towards ``target``."""
    zc = (target - eye) / np.linalg.norm(target - eye)
    a = np.array([np.cos(spin), np.sin(spin), 0.3])
    xc = np.cross(a, zc)
    xc /= np.linalg.norm(xc)
    R_wc = np.column_stack([xc, np.cross(zc, xc), zc])
    q = quat_from_matrix(R_wc @ R_BODY_CAM.T)
    return eye - matrix_from_quat(q) @ rig_offset, q


def poses(w: World, n: int, seed: int):
    """(drone positions (READS, n, 3), quaternions (READS, n, 4), deck body positions, deck
    quaternions) of n worlds over consecutive reads: views from above (mostly detected), off to
    the side (border / outside), grazing (too oblique), from below the plate (occluded), looking
    away (behind the camera)."""
    rng = np.random.default_rng(seed)
    off = np.asarray(w.config.rig.camera_position)
    home = w.config.stewart.home_height
    out = np.zeros((READS, n, 3)), np.zeros((READS, n, 4)), np.zeros((READS, n, 3)), np.zeros((READS, n, 4))
    for i in range(n):
        kind = i % 6
        deck_rpy = rng.uniform(-0.25, 0.25, 3)
        deck_pos = np.array([*rng.uniform(-0.2, 0.2, 2), home + rng.uniform(-0.15, 0.15)])
        Rd = matrix_from_quat(p.getQuaternionFromEuler(deck_rpy.tolist()))
        target = deck_pos + Rd @ np.array([*rng.uniform(-0.15, 0.15, 2), 0.0])
        if kind in (0, 1):  # above, tag in view
            eye = target + Rd @ np.array([*rng.uniform(-0.4, 0.4, 2), rng.uniform(0.5, 3.0)])
        elif kind == 2:  # above, aimed beside the tag: at or over the border
            eye = target + Rd @ np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(0.6, 1.5)])
            centre = target
            target = target + Rd @ np.array([*rng.choice([-1, 1], 2) * rng.uniform(0.2, 1.2, 2), 0.0])
        elif kind == 3:  # grazing
            a = rng.uniform(0, 2 * np.pi)
            eye = target + Rd @ np.array([2.0 * np.cos(a), 2.0 * np.sin(a), rng.uniform(0.05, 0.4)])
        elif kind == 4:  # from below the plate, off to the side
            a = rng.uniform(0, 2 * np.pi)
            r = rng.uniform(0.6, 0.9)
            eye = target + Rd @ np.array([r * np.cos(a), r * np.sin(a), -rng.uniform(0.3, 0.5)])
        else:  # looking away
            eye = target + Rd @ np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(0.5, 2.0)])
            target = 2 * eye - target
        step = rng.normal(0.0, 2e-4, 3)  # m per read: corners move by a fraction of a pixel
        deck_q = np.asarray(p.getQuaternionFromEuler(deck_rpy.tolist()))
        body = (deck_pos - Rd[:, 2] * w.config.deck.thickness / 2, deck_q)
        if kind == 2 and i % 12 == 8:  # aimed so that the quiet zone ends ~2.5 px inside the border
            target = aim_at_quiet_margin(w, eye, centre, 0.7 * i, body)
        for k in range(READS):
            pos, q = look_at(eye + k * step, target, 0.7 * i, off)
            out[0][k, i], out[1][k, i] = pos, q
            out[2][k, i], out[3][k, i] = body
    return out


def aim_at_quiet_margin(w: World, eye, start, spin: float, body) -> np.ndarray:
    """The aim point between ``start`` and the point 1 m beyond it (along the first image axis)
    that puts the quiet zone's nearest corner 2.5 px inside the image (bisection)."""
    cam = w.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    off = np.asarray(w.config.rig.camera_position)
    pos, q = look_at(eye, start, spin, off)
    direction = matrix_from_quat(q) @ R_BODY_CAM[:, 0]

    def margin(t: float) -> float:
        pos, q = look_at(eye, start + t * direction, spin, off)
        state, _, _ = place(w, pos, q, *body)
        f, _ = cam.features(state)
        return -np.inf if f is None else f.quiet_margin

    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if margin(mid) > 2.5 else (lo, mid)
    return start + lo * direction


def place(w: World, pos, q, deck_pos, deck_q):
    """Put the drone and the deck in PyBullet; (BodyState, deck position, deck rotation) as the
    scalar camera sees them."""
    p.resetBasePositionAndOrientation(
        w.deck.body, deck_pos.tolist(), deck_q.tolist(), physicsClientId=w.client
    )
    p.resetBasePositionAndOrientation(w.quad.body, pos.tolist(), q.tolist(), physicsClientId=w.client)
    R = matrix_from_quat(q)
    cam = w.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    dp, dR = cam._deck_pose()
    return BodyState(0.0, pos, R, q, np.zeros(3), np.zeros(3), np.zeros(3)), dp, dR


def occlusion_bracket(cam: ClosedFormTagCamera, pos, R, dp, dR, e: float) -> np.ndarray:
    """(N,) occlusion of the camera's rays with every collision surface moved out by ``e`` (m)."""
    eye = pos + R @ np.asarray(cam._cam_offset)
    targets = (dp[:, None, :] + cam._points_deck @ dR.transpose(0, 2, 1))[:, [0, 1, 2, 3, 8]]
    d = targets - eye[:, None]
    ends = targets - d * (RAY_MARGIN_M / np.linalg.norm(d, axis=2))[..., None]
    s = cam.scene
    h = s.deck_half_extents
    grown = RayScene((h[0] + e, h[1] + e, h[2] + e), s.base_radius + e, s.base_height + e)
    starts = np.broadcast_to(eye[:, None], ends.shape)
    hit = cast_rays(starts, ends - starts, 1.0, dp + e * dR[:, :, 2], dR, grown).hit
    centres, halves = drone_boxes()
    sb = to_local(np.ascontiguousarray(starts - pos[:, None]), R)[:, :, None] - centres
    db = np.broadcast_to(to_local(ends - starts, R)[:, :, None], sb.shape)
    f, _ = _box_entry(sb, db, np.broadcast_to(halves + e, sb.shape))
    return hit.any(axis=1) | np.isfinite(f).any(axis=(1, 2))


def scenario(w: World, n: int, seed: int):
    """Poses (PyBullet's) of n worlds without an ambiguous occlusion, each world's scalar readings
    over READS reads, and the inputs of the closed-form reads."""
    cam = w.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    bcam = closed_form(w)
    dpos, dq, bpos, bq = poses(w, n, seed)
    inputs = []
    for k in range(READS):
        rows = [place(w, dpos[k, i], dq[k, i], bpos[k, i], bq[k, i]) for i in range(n)]
        inputs.append(
            (
                np.array([r[0].position for r in rows]),
                np.array([r[0].rotation for r in rows]),
                np.array([r[1] for r in rows]),
                np.array([r[2] for r in rows]),
            )
        )
    # worlds 0, 2, 4, ... start with a drawn field, the others draw it at the first use
    tracks = [CornerTrack(np.random.default_rng([seed, i, 1]) if i % 2 == 0 else None) for i in range(n)]
    rngs = [np.random.default_rng([seed, i]) for i in range(n)]
    # rows whose occlusion Bullet may decide either way while the model reports the tag
    bad = np.zeros(n, dtype=bool)
    probe_tracks, probe_rngs = copy.deepcopy(tracks), copy.deepcopy(rngs)
    for pos, R, dp, dR in inputs:
        st = bcam.read(pos, R, dp, dR, probe_tracks, probe_rngs)["tag_status"]
        amb = occlusion_bracket(bcam, pos, R, dp, dR, EPS) != occlusion_bracket(bcam, pos, R, dp, dR, -EPS)
        bad |= amb & ((st == 0) | (st == TAG_STATUS.index("tag occluded")))
    keep = np.flatnonzero(~bad)
    inputs = [tuple(a[keep] for a in x) for x in inputs]
    dpos, dq, bpos, bq = dpos[:, keep], dq[:, keep], bpos[:, keep], bq[:, keep]
    tracks, rngs = [tracks[i] for i in keep], [rngs[i] for i in keep]
    expected = []
    s_tracks, s_rngs = copy.deepcopy(tracks), copy.deepcopy(rngs)
    for k in range(READS):
        row = []
        for i in range(len(keep)):
            state, _, _ = place(w, dpos[k, i], dq[k, i], bpos[k, i], bq[k, i])
            cam.track = s_tracks[i]
            row.append(cam.read(state, 0.05, s_rngs[i]))
        expected.append(row)
    return bcam, inputs, tracks, rngs, expected, int(bad.sum()), s_rngs


def compare(got: dict, expected: list[dict]) -> float:
    """Assert every row equals its scalar reading; the largest corner difference (px)."""
    worst = 0.0
    for i, e in enumerate(expected):
        assert got["tag_status"][i] == e["tag_status"], (i, got["tag_reason"][i], e["tag_reason"])
        assert got["tag_reason"][i] == e["tag_reason"]
        assert got["tag_detected"][i] == e["tag_detected"]
        worst = max(worst, float(np.abs(got["tag_corners"][i] - e["tag_corners"]).max()))
    return worst


def test_rows_match_scalar_reads(world: World) -> None:
    bcam, inputs, tracks, rngs, expected, dropped, after = scenario(world, 96, 11)
    n = len(tracks)
    assert n >= 80  # few poses are ambiguous (grazing views the model still reports)
    batch = CornerTracks.of(tracks)
    worst = 0.0
    statuses = []
    for (pos, R, dp, dR), exp in zip(inputs, expected, strict=True):
        got = bcam.read(pos, R, dp, dR, batch, rngs)
        assert got["tag_corners"].shape == (n, 4, 2) and got["tag_status"].shape == (n,)
        worst = max(worst, compare(got, exp))
        statuses.append(got["tag_status"])
    seen = {TAG_STATUS[s] for s in np.concatenate(statuses).tolist()}
    print(f"{n} worlds ({dropped} ambiguous poses left out), {READS} reads: max |corner diff| {worst:.3g} px")
    print("reasons:", sorted(seen))
    assert worst <= 1e-12
    for reason in (
        "",
        "tag outside the image",
        "tag partly outside the image (too close to its border)",
        "tag seen too obliquely",
        "tag's quiet zone cut by the image border",
        "tag outside the camera's depth range",
        "tag occluded",
    ):
        assert reason in seen, reason
    # the generators end where the scalar ones do
    for r, e in zip(rngs, after, strict=True):
        assert r.random() == e.random()


def test_rows_independent_of_n(world: World) -> None:
    bcam, inputs, tracks, rngs, _, _, _ = scenario(world, 24, 5)
    n = len(tracks)

    def run(rows: list[int]) -> list[dict]:
        tr = CornerTracks.of([copy.deepcopy(tracks[i]) for i in rows])
        rg = [copy.deepcopy(rngs[i]) for i in rows]
        return [bcam.read(*(a[rows] for a in x), tr, rg) for x in inputs]

    full = run(list(range(n)))
    for rows in ([3], [n - 1], list(range(1, n, 3))):
        part = run(rows)
        for k in range(READS):
            for key in KEYS:
                assert np.array_equal(part[k][key], full[k][key][rows]), (rows, k, key)


def test_scalar_tracks_are_updated(world: World) -> None:
    """A list of CornerTrack is accepted; a field drawn by the read is written back to its track."""
    bcam, inputs, tracks, rngs, expected, _, _ = scenario(world, 12, 3)
    for x, exp in zip(inputs, expected, strict=True):
        compare(bcam.read(*x, tracks, rngs), exp)
    first = bcam.read(*inputs[0], CornerTracks.of(tracks), copy.deepcopy(rngs))
    assert first["tag_detected"].any()
    for t in tracks[1::2]:  # drawn at their first use in range
        assert t.omega is not None


def test_refuses_bad_input(world: World) -> None:
    cam = world.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    with pytest.raises(TypeError, match="scene"):
        ClosedFormTagCamera(cam.camera, world.config.rig, None, 0.4, cam.model)  # type: ignore[arg-type]
    bcam = closed_form(world)
    with pytest.raises(ValueError, match="generators"):
        bcam.read(
            np.zeros((2, 3)),
            np.tile(np.eye(3), (2, 1, 1)),
            np.zeros((2, 3)),
            np.tile(np.eye(3), (2, 1, 1)),
            CornerTracks(2),
            [np.random.default_rng(0)],
        )


def test_the_projected_camera_with_closed_form_rays_reads_its_row(world: World) -> None:
    """ProjectedTagCamera(closed_form=True) reads, at each read of each world, the closed-form
    camera's row of that world, bit for bit, from the same track and generator."""
    cam = world.sensors[TAG_CAMERA]
    assert isinstance(cam, ProjectedTagCamera)
    own = ProjectedTagCamera(
        world.client,
        cam.camera,
        world.config.rig,
        world.deck,
        world.config.deck.tag_size,
        cam.model,
        closed_form=True,
    )
    assert own.closed_form is not None and cam.closed_form is None
    n, seed = 12, 7
    dpos, dq, bpos, bq = poses(world, n, seed)
    tracks = [CornerTrack(np.random.default_rng([seed, i, 1]) if i % 2 == 0 else None) for i in range(n)]
    rngs = [np.random.default_rng([seed, i]) for i in range(n)]
    batch, batch_rngs = CornerTracks.of(copy.deepcopy(tracks)), copy.deepcopy(rngs)
    bcam = closed_form(world)
    seen = set()
    for k in range(READS):
        rows, inputs = [], []
        for i in range(n):
            state, dp, dR = place(world, dpos[k, i], dq[k, i], bpos[k, i], bq[k, i])
            own.track = tracks[i]
            rows.append(own.read(state, 0.05, rngs[i]))
            inputs.append((state.position, state.rotation, dp, dR))
        got = bcam.read(*(np.array(a) for a in zip(*inputs, strict=True)), batch, batch_rngs)
        for i, row in enumerate(rows):
            for key in KEYS:
                assert np.array_equal(row[key], got[key][i]), (k, i, key)
            seen.add(str(row["tag_reason"]))
    assert "" in seen and "tag occluded" in seen
    for r, b in zip(rngs, batch_rngs, strict=True):
        assert r.random() == b.random()
