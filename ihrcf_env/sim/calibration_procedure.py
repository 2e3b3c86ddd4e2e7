"""Simulated calibration procedures of IHRCF (Sefidgar & Landry 2022, sections 2.1 and 2.2).

* :func:`run_chessboard`: a 7 x 9 inner-corner chessboard is placed at random poses (seeded) in front
  of the drone's downward camera, each frame goes through ``find_chessboard`` (grey image,
  ``findChessboardCorners`` + ``cornerSubPix``) and the corners of all views through
  ``cv2.calibrateCamera`` -> K, distortion, RMS.
* :func:`run_ascent`: the drone hovers over the static, level deck, on which four coloured pads
  (blue, green, yellow, red) are centred on the touch points of ps1..ps4. It climbs in ``stages``
  steps from ``bottom`` to ``top`` (camera-to-deck range, m) with ``World.set_velocity_setpoint``,
  holds each stage for the rest of ``stage_period_s``, then takes one image and the four ideal
  ranges. Each pad is segmented (YCbCr eq. 2, Table 1, filled convex hull, centroid eq. 7); a stage
  where any pad is missing or cut by the image border is skipped and reported.
* :func:`run_calibration`: both, in a fresh :class:`World`, -> a
  :class:`~ihrcf_env.core.calibration.Calibration`.

The pads are fixed on the deck (placed once at the first stage's touch points), like real pads;
the report gives how far the beams' touch points wandered from the pad centres during the
ascent (the position hold keeps it at micrometres on a static deck).

Everything is deterministic: the same settings and seed give a byte-identical calibration file
(the report holds no wall-clock times).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import pybullet as p
from numpy.typing import ArrayLike, NDArray

from ihrcf_env._version import __version__
from ihrcf_env.config.sensors import CameraConfig, ToFConfig
from ihrcf_env.config.world import WorldConfig
from ihrcf_env.core.calibration import (
    Calibration,
    IntrinsicsResult,
    RangePixelTable,
    calibrate_intrinsics,
    find_chessboard,
    segment_pads,
)
from ihrcf_env.core.frames import matrix_from_euler
from ihrcf_env.core.profiles import StaticProfile
from ihrcf_env.core.rig import PAD_COLOURS, SensorRig, intrinsics_from_fov
from ihrcf_env.sim.calibration_scene import DEFAULT_PAD_RADIUS, PAD_RGB, CalibrationScene
from ihrcf_env.sim.sensors import ToFArray
from ihrcf_env.sim.world import World

#: ``progress(phase, done, total)``: called after every chessboard attempt / ascent stage.
Progress = Callable[[str, int, int], None]


class CalibrationFailed(RuntimeError):
    """The simulated procedure could not produce a usable calibration (the message says why)."""


@dataclass(frozen=True)
class ChessboardSettings:
    """Chessboard capture (section 2.1). Lengths in m, angles in degrees.

    The board is placed in the camera frame at a depth in ``depth_range``, tilted by an angle in
    ``tilt_deg`` about a random in-plane axis, turned by a random angle about its normal, and
    shifted so that its projection (nominal pinhole of the camera config) lies at least
    ``border_px`` inside the image. Views where OpenCV does not find the board are retried, up to
    ``max_attempts_factor * n_views`` attempts in all.
    """

    n_views: int = 30
    pattern: tuple[int, int] = (7, 9)
    square: float = 0.04
    depth_range: tuple[float, float] = (0.45, 0.85)
    tilt_deg: tuple[float, float] = (10.0, 40.0)
    border_px: float = 10.0
    max_attempts_factor: int = 3
    calibrate_flags: int = 0

    def __post_init__(self) -> None:
        if self.n_views < 3:
            raise ValueError(f"the chessboard calibration needs at least 3 views, got n_views={self.n_views}")
        lo, hi = self.depth_range
        if not (0 < lo <= hi):
            raise ValueError(f"depth_range must satisfy 0 < lo <= hi (m), got {self.depth_range}")
        if not (0 <= self.tilt_deg[0] <= self.tilt_deg[1] < 80):
            raise ValueError(f"tilt_deg must satisfy 0 <= lo <= hi < 80, got {self.tilt_deg}")
        if self.max_attempts_factor < 1:
            raise ValueError("max_attempts_factor must be >= 1")


@dataclass(frozen=True)
class AscentSettings:
    """Camera-range calibration ascent (section 2.2). Ranges are camera-to-deck along the optical
    axis (m); ``top=None`` means the ToF sensors' ``max_range``.

    Attributes:
        stages: number of stages (paper: 120), evenly spaced from ``bottom`` to ``top``.
        bottom, top: range of the first and last stage (m).
        stage_period_s: sim time per stage, climb included (paper: 3 s).
        climb_speed: vertical speed command while climbing (m/s).
        pad_radius: calibration pad radius (m).
        min_usable_stages: fewer usable stages than this is an error (PCHIP needs >= 4); default
            half the stages (at least 4), see :attr:`min_usable`.
    """

    stages: int = 120
    bottom: float = 0.15
    top: float | None = None
    stage_period_s: float = 3.0
    climb_speed: float = 0.5
    pad_radius: float = DEFAULT_PAD_RADIUS
    min_usable_stages: int | None = None

    def __post_init__(self) -> None:
        if self.stages < 4:
            raise ValueError(f"stages must be >= 4 (PCHIP needs 4 samples), got {self.stages}")
        if not (math.isfinite(self.bottom) and self.bottom > 0):
            raise ValueError(f"bottom must be a positive range (m), got {self.bottom!r}")
        if self.top is not None and not (math.isfinite(self.top) and self.top > self.bottom):
            raise ValueError(f"top ({self.top!r} m) must be greater than bottom ({self.bottom} m)")
        if not (self.stage_period_s > 0 and self.climb_speed > 0):
            raise ValueError("stage_period_s and climb_speed must be positive")
        if self.min_usable_stages is not None and not (4 <= self.min_usable_stages <= self.stages):
            raise ValueError(
                f"min_usable_stages must be in [4, stages={self.stages}], got {self.min_usable_stages}"
            )

    @property
    def min_usable(self) -> int:
        """Fewest usable stages accepted."""
        if self.min_usable_stages is not None:
            return self.min_usable_stages
        return max(4, math.ceil(self.stages / 2))


# ------------------------------------------------------------------------------------------
# Chessboard (section 2.1)
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ChessboardResult:
    """Zhang calibration from rendered chessboard views, with its error against the renderer's K."""

    intrinsics: IntrinsicsResult
    K_true: NDArray[np.float64]
    views_tried: int

    @property
    def focal_error_rel(self) -> float:
        """Largest relative focal length error, ``max(|fx - fx0| / fx0, |fy - fy0| / fy0)``."""
        K, K0 = self.intrinsics.K, self.K_true
        return float(max(abs(K[0, 0] - K0[0, 0]) / K0[0, 0], abs(K[1, 1] - K0[1, 1]) / K0[1, 1]))

    @property
    def principal_point_error_px(self) -> float:
        """Distance (px) between the estimated and the true principal point."""
        K, K0 = self.intrinsics.K, self.K_true
        return float(math.hypot(K[0, 2] - K0[0, 2], K[1, 2] - K0[1, 2]))

    def report(self) -> dict[str, Any]:
        return {
            "views_tried": self.views_tried,
            "views_used": self.intrinsics.n_views,
            "rms_px": self.intrinsics.rms,
            "focal_error_rel": self.focal_error_rel,
            "principal_point_error_px": self.principal_point_error_px,
            "K_true_renderer": self.K_true.tolist(),
        }


def _rotation_about(axis: NDArray[np.float64], angle: float) -> NDArray[np.float64]:
    """Rodrigues rotation matrix about a unit ``axis`` by ``angle`` (rad)."""
    k = axis / np.linalg.norm(axis)
    Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * Kx + (1 - math.cos(angle)) * (Kx @ Kx)


def sample_board_pose(
    rng: np.random.Generator,
    settings: ChessboardSettings,
    camera: CameraConfig,
    outline_board: NDArray[np.float64],
    max_tries: int = 200,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A random board pose ``(R_cam_board, t_cam_board)`` in the camera frame (OpenCV axes, m) whose
    whole outline (4, 3) projects at least ``border_px`` inside the image (nominal pinhole K)."""
    K = intrinsics_from_fov(camera.width, camera.height, camera.fov)
    W, H, b = camera.width, camera.height, settings.border_px
    flip = np.diag([1.0, -1.0, -1.0])  # board z towards the camera
    for _ in range(max_tries):
        gamma = rng.uniform(0.0, 2 * math.pi)
        phi = rng.uniform(0.0, 2 * math.pi)
        tilt = math.radians(rng.uniform(*settings.tilt_deg))
        depth = rng.uniform(*settings.depth_range)
        u, v = rng.uniform(0.0, W - 1), rng.uniform(0.0, H - 1)
        R = (
            _rotation_about(np.array([math.cos(phi), math.sin(phi), 0.0]), tilt)
            @ flip
            @ matrix_from_euler(0.0, 0.0, gamma)
        )
        t = depth * np.linalg.solve(K, np.array([u, v, 1.0]))
        pts = outline_board @ R.T + t
        if np.any(pts[:, 2] <= camera.near * 2):
            continue
        uv = pts @ K.T
        uv = uv[:, :2] / uv[:, 2:]
        if np.all((uv[:, 0] >= b) & (uv[:, 0] <= W - 1 - b) & (uv[:, 1] >= b) & (uv[:, 1] <= H - 1 - b)):
            return R, t
    raise CalibrationFailed(
        f"could not place the chessboard inside a {W}x{H} image in {max_tries} tries: make the board "
        "smaller or the depth range larger"
    )


def run_chessboard(
    world: World,
    scene: CalibrationScene,
    settings: ChessboardSettings,
    rng: np.random.Generator,
    progress: Progress | None = None,
) -> ChessboardResult:
    """Capture ``settings.n_views`` chessboard views with the drone's camera and calibrate.

    The drone stays where it is; the board is moved in front of the camera (equivalent to moving
    the camera). Raises :class:`CalibrationFailed` if fewer than ``n_views`` views are found
    within the allowed attempts.
    """
    cam = world.config.camera
    if cam is None or world.camera is None:
        raise CalibrationFailed("the chessboard calibration needs a camera (WorldConfig.camera is None)")
    if (scene.pattern, scene.square) != (tuple(settings.pattern), settings.square):
        raise ValueError("scene and settings disagree on the chessboard pattern/square")
    pos, R_wb = world.drone_pose()
    eye, R_wc = world.camera.pose(pos, R_wb)
    outline = scene.board_outline()
    scene.hide_pads()
    corners: list[NDArray[np.float64]] = []
    tried = 0
    max_attempts = settings.max_attempts_factor * settings.n_views
    while len(corners) < settings.n_views and tried < max_attempts:
        R_cb, t_cb = sample_board_pose(rng, settings, cam, outline)
        scene.place_board(eye + R_wc @ t_cb, R_wc @ R_cb)
        img = scene.render()
        tried += 1
        pts = find_chessboard(img, settings.pattern)
        if pts is not None:
            corners.append(pts)
        if progress is not None:
            progress("chessboard", len(corners), settings.n_views)
    scene.hide_board()
    if len(corners) < settings.n_views:
        raise CalibrationFailed(
            f"the chessboard was found in only {len(corners)} of {tried} rendered views "
            f"(need {settings.n_views}); check the camera config and the board size"
        )
    # cv2.calibrateCamera's multi-threaded reductions differ in the last bits from run to run; one
    # thread makes the result (and so the calibration file) reproducible.
    n_threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        size = (cam.width, cam.height)
        res = calibrate_intrinsics(corners, settings.pattern, settings.square, size, settings.calibrate_flags)
    finally:
        cv2.setNumThreads(n_threads)
    return ChessboardResult(intrinsics=res, K_true=cam.intrinsics.copy(), views_tried=tried)


# ------------------------------------------------------------------------------------------
# Ascent (section 2.2)
# ------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class StageRecord:
    """One ascent stage: ``ranges`` (4,) ideal ranges of ps1..ps4 (m), ``pixels`` (4, 2) pad
    centroids (NaN where not found), ``found`` (4,), hover ``speed`` (m/s) at capture and ``drift``
    (m): largest distance between a beam's touch point and its pad centre."""

    index: int
    target: float
    ranges: NDArray[np.float64]
    pixels: NDArray[np.float64]
    found: NDArray[np.bool_]
    speed: float
    drift: float
    reason: str = ""

    @property
    def usable(self) -> bool:
        return not self.reason

    def skip_report(self) -> dict[str, Any]:
        return {"stage": self.index, "range_m": float(np.mean(self.ranges)), "reason": self.reason}


@dataclass(eq=False)
class AscentResult:
    """All stages of an ascent and the range -> pixel table built from the usable ones."""

    stages: list[StageRecord]
    table: RangePixelTable
    bottom: float
    top: float

    @property
    def usable(self) -> list[StageRecord]:
        return [s for s in self.stages if s.usable]

    @property
    def skipped(self) -> list[StageRecord]:
        return [s for s in self.stages if not s.usable]


def _layout_ok(px: NDArray[np.float64]) -> bool:
    """Pad centroids in the rig's arrangement: ps1 top-left, ps2 top-right, ps3 bottom-right, ps4
    bottom-left (image u right, v down)."""
    u, v = px[:, 0], px[:, 1]
    return bool(u[0] < u[1] and u[3] < u[2] and v[0] < v[3] and v[1] < v[2])


def stage_targets(settings: AscentSettings, top: float) -> NDArray[np.float64]:
    """(stages,) evenly spaced stage ranges from ``bottom`` to ``top`` (m)."""
    return np.linspace(settings.bottom, top, settings.stages)


def run_ascent(
    world: World,
    scene: CalibrationScene,
    settings: AscentSettings,
    progress: Progress | None = None,
) -> AscentResult:
    """Fly the calibration ascent over the world's (static, level) deck and build the table.

    The world is reset with a static deck and the drone hovering at the first stage. Raises
    :class:`CalibrationFailed` when fewer than ``settings.min_usable`` stages are usable.
    """
    cfg = world.config
    top = float(settings.top) if settings.top is not None else float(cfg.tof.max_range)
    if top <= settings.bottom:
        raise ValueError(f"top ({top} m) must be greater than bottom ({settings.bottom} m)")
    rig = cfg.rig
    cam_z = float(rig.camera_position[2])  # body frame; the sensors share the camera plane
    targets = stage_targets(settings, top)
    # Ideal range readings, with head-room so that a stage at exactly the sensors' max range hits.
    tof = ToFArray(world.client, ToFConfig(max_range=top * 1.5 + 1.0, noise="ideal"), rig)
    sensors_body = rig.sensor_positions_body

    world.reset(StaticProfile(), 1.0, altitude=float(targets[0]) - cam_z)
    deck_pos, R_wd = world.deck.pose()
    dt_ctrl = 1.0 / cfg.control_hz
    steps_per_stage = max(1, round(settings.stage_period_s / dt_ctrl))
    ref = float(targets[0])
    pads: NDArray[np.float64] | None = None
    stages: list[StageRecord] = []
    scene.hide_board()
    for k, target in enumerate(targets):
        # Climb: a constant vz for a whole number of control periods moves the position set-point
        # exactly to the stage altitude; then hold (zero set-point) for the rest of the period.
        dz = float(target) - ref
        n_climb = min(steps_per_stage, math.ceil(abs(dz) / (settings.climb_speed * dt_ctrl))) if dz else 0
        for i in range(steps_per_stage):
            vz = dz / (n_climb * dt_ctrl) if i < n_climb else 0.0
            world.set_velocity_setpoint(np.array([0.0, 0.0, vz, 0.0]))
            world.step()
        ref = float(target)
        pos, R_wb = world.drone_pose()
        ranges, hit = tof.true_ranges(pos, R_wb)
        starts = sensors_body @ R_wb.T + pos
        touch = starts - R_wb[:, 2] * ranges[:, None]
        if pads is None:
            pads = touch.copy()
            scene.place_pads(pads, R_wd)
        # Distance from each touch point to its pad centre, within the deck plane.
        off = (touch - pads) @ R_wd
        drift = float(np.max(np.linalg.norm(off[:, :2], axis=1)))
        speed = float(np.linalg.norm(p.getBaseVelocity(world.quad.body, physicsClientId=world.client)[0]))
        img = scene.render()
        dets = segment_pads(img)
        found = np.array([dets[c] is not None for c in PAD_COLOURS])
        pixels = np.full((4, 2), np.nan)
        for i, c in enumerate(PAD_COLOURS):
            det = dets[c]
            if det is not None:
                pixels[i] = det.centroid
        reason = ""
        if not np.all(hit):
            reason = "range sensor missed the deck"
        elif not np.all(found):
            missing = [c for c, f in zip(PAD_COLOURS, found, strict=True) if not f]
            reason = "pad not found or cut by the image border: " + ", ".join(missing)
        elif not _layout_ok(pixels):
            reason = "pads not in the rig's layout"
        stages.append(
            StageRecord(
                index=k,
                target=float(target),
                ranges=ranges.copy(),
                pixels=pixels,
                found=found,
                speed=speed,
                drift=drift,
                reason=reason,
            )
        )
        if progress is not None:
            progress("ascent", k + 1, len(targets))
    scene.hide_pads()
    scene.restore_tag()
    usable = [s for s in stages if s.usable]
    if len(usable) < settings.min_usable:
        reasons = sorted({s.reason for s in stages if s.reason})
        raise CalibrationFailed(
            f"only {len(usable)} of {len(stages)} calibration stages were usable (need at least "
            f"{settings.min_usable}); reasons: {'; '.join(reasons) or 'none'}. Check the pad "
            "colours/lighting, the pad radius, and bottom/top against the camera's field of view."
        )
    r = np.array([s.ranges for s in usable])
    px = np.array([s.pixels for s in usable])
    table = RangePixelTable.from_samples(r, px)
    return AscentResult(stages=stages, table=table, bottom=settings.bottom, top=top)


# ------------------------------------------------------------------------------------------
# Whole calibration
# ------------------------------------------------------------------------------------------


def true_touch_pixels(
    ranges: ArrayLike, rig: SensorRig, K: NDArray[np.float64], dist: ArrayLike | None = None
) -> NDArray[np.float64]:
    """(N, 4, 2) true image of the touch points ``(x_i, y_i, d_i)`` (camera frame, m) for ranges (N, 4):
    ``K`` and the OpenCV distortion vector ``dist`` (None: ideal pinhole)."""
    d = np.atleast_2d(np.asarray(ranges, dtype=np.float64))
    xy = rig.sensor_xy_cam
    pts = np.concatenate([np.broadcast_to(xy, (d.shape[0], 4, 2)), d[..., None]], axis=-1).reshape(-1, 3)
    dc = np.zeros(5) if dist is None else np.asarray(dist, dtype=np.float64)
    uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, dc)
    return np.asarray(uv, dtype=np.float64).reshape(d.shape[0], 4, 2)


def table_errors_px(
    table: RangePixelTable,
    ranges: ArrayLike,
    rig: SensorRig,
    K: NDArray[np.float64],
    dist: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """(N, 4) distance (px) between the table's touch pixels for ``ranges`` (N, 4) (m) and the true
    projection :func:`true_touch_pixels`."""
    d = np.atleast_2d(np.asarray(ranges, dtype=np.float64))
    truth = true_touch_pixels(d, rig, K, dist)
    out = np.empty(d.shape)
    for n, row in enumerate(d):
        uv, _ = table(row)
        out[n] = np.linalg.norm(uv - truth[n], axis=1)
    return out


@dataclass(eq=False)
class CalibrationRun:
    """Everything a calibration run produced: the file contents and the raw results."""

    calibration: Calibration
    chessboard: ChessboardResult
    ascent: AscentResult
    table_check_px: dict[str, float] = field(default_factory=dict)


def run_calibration(
    camera: CameraConfig | None = None,
    rig: SensorRig | None = None,
    tof: ToFConfig | None = None,
    ascent: AscentSettings | None = None,
    chessboard: ChessboardSettings | None = None,
    seed: int | None = 0,
    progress: Progress | None = None,
) -> CalibrationRun:
    """Run both procedures in a fresh world and assemble the calibration file contents.

    ``seed`` drives the chessboard poses (the ascent is deterministic). The report records the
    procedure settings, skipped stages, the chessboard's errors against the renderer's true K and
    the table's error against the true projection at the sample ranges (ground truth kept for
    reporting; estimators use only ``tables``, ``K`` and ``dist``).
    """
    camera = camera if camera is not None else CameraConfig()
    rig = rig if rig is not None else SensorRig()
    tof = tof if tof is not None else ToFConfig()
    ascent = ascent if ascent is not None else AscentSettings()
    chessboard = chessboard if chessboard is not None else ChessboardSettings()
    rng = np.random.default_rng(seed)
    world = World(WorldConfig(camera=camera, rig=rig, tof=tof))
    try:
        scene = CalibrationScene(
            world, pad_radius=ascent.pad_radius, pattern=chessboard.pattern, square=chessboard.square
        )
        try:
            # Chessboard first, with the drone hovering high enough that the whole board, placed in
            # front of the camera, stays well above the deck.
            world.reset(StaticProfile(), 1.0, altitude=chessboard.depth_range[1] + 1.0)
            cb = run_chessboard(world, scene, chessboard, rng, progress)
            asc = run_ascent(world, scene, ascent, progress)
        finally:
            scene.close()
    finally:
        world.close()

    usable = asc.usable
    samples = np.array([s.ranges for s in usable])
    err = table_errors_px(asc.table, samples, rig, camera.intrinsics, camera.distortion_coefficients)
    check = {"max": float(err.max()), "mean": float(err.mean())}
    report: dict[str, Any] = {
        "procedure": {
            "stages": ascent.stages,
            "bottom_m": ascent.bottom,
            "top_m": asc.top,
            "stage_period_s": ascent.stage_period_s,
            "climb_speed_mps": ascent.climb_speed,
            "pad_radius_m": ascent.pad_radius,
            "pad_rgb": {c: list(PAD_RGB[c]) for c in PAD_COLOURS},
            "light": {
                "direction": list(camera.light_direction),
                "ambient": camera.ambient,
                "diffuse": camera.diffuse,
                "specular": camera.specular,
            },
            "chessboard_pattern": list(chessboard.pattern),
            "chessboard_square_m": chessboard.square,
            "chessboard_views": chessboard.n_views,
            "camera_distortion_true": list(camera.distortion),
        },
        "stages_used": len(usable),
        "stages_skipped": [s.skip_report() for s in asc.skipped],
        "table_span_m": [float(asc.table.spans[:, 0].min()), float(asc.table.spans[:, 1].max())],
        "table_error_at_samples_px": check,
        "max_hover_speed_at_capture_mps": max(s.speed for s in usable),
        "max_pad_drift_m": max(s.drift for s in usable),
        "chessboard": cb.report(),
    }
    cal = Calibration(
        image_width=camera.width,
        image_height=camera.height,
        fov=camera.fov,
        lens_distortion=camera.distortion,
        rig=rig.to_dict(),
        tables=asc.table,
        K=cb.intrinsics.K,
        dist=cb.intrinsics.dist,
        chessboard_rms=cb.intrinsics.rms,
        seed=seed,
        created_with=f"ihrcf_env {__version__} (simulated calibration)",
        report=report,
    )
    return CalibrationRun(calibration=cal, chessboard=cb, ascent=asc, table_check_px=check)


__all__ = [
    "AscentResult",
    "AscentSettings",
    "CalibrationFailed",
    "CalibrationRun",
    "ChessboardResult",
    "ChessboardSettings",
    "Progress",
    "StageRecord",
    "run_ascent",
    "run_calibration",
    "run_chessboard",
    "sample_board_pose",
    "stage_targets",
    "table_errors_px",
    "true_touch_pixels",
]
