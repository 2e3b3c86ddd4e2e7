"""What one episode's recording holds, gathered step by step, and how it is sent to Rerun.

:class:`EpisodeLog` collects plain numpy values while the episode runs (no Rerun call per step)
and :meth:`EpisodeLog.send` writes them to a ``rerun.RecordingStream`` as columns on the
simulated-time timeline :data:`TIMELINE` (seconds since reset). Entity paths (:data:`ENTITIES`):

=====================================  ========================================================
path                                   what it shows
=====================================  ========================================================
``world/deck``                         deck pose (world frame, Transform3D)
``world/deck/plate``, ``/tag``         the deck plate and the tag (static boxes)
``world/drone``                        drone body pose (world frame, Transform3D)
``world/drone/body``                   the drone (static box)
``world/drone/tof``                    the four ToF beams to their hits (green valid, red invalid)
``world/drone/camera``                 the camera frustum (static pinhole, body frame)
``world/drone/estimates/<name>``       each estimator's deck pose (body frame) while valid
``world/trajectory``                   the drone's whole path (world frame)
``camera/image``                       the camera image (JPEG) when the frame carries it
``camera/corners``, ``camera/tag``     the detected tag corners and their outline (px)
``truth/position``, ``truth/euler``    true deck pose in the body frame (m, rad)
``estimates/<name>/position``, ...     each estimate (m, rad), ``valid`` (0/1), ``residual``,
                                       ``position_error`` (m) and ``angle_error`` (rad) against
                                       the truth, ``reason`` (text when it changes)
``tof/ranges``, ``tof/valid``          ranges (m) and valid flags of ps1..ps4
``action``                             the action passed to ``step`` (as given)
``reward/<term>``, ``reward/total``    the reward terms of ``info`` and the step reward
``wind``                               wind velocity (world frame, m/s)
``faults/frame_lost``, ``dead_beams``  1 when the camera frame was lost; invalid ToF beams
``events/tag``, ``events/outcome``    tag status changes; the outcome, touchdown figures
=====================================  ========================================================
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ihrcf_env.core.frames import R_BODY_CAM

__all__ = ["ENTITIES", "INVALID_BEAM", "JPEG_QUALITY", "TIMELINE", "EpisodeLog", "SceneGeometry", "blueprint"]

#: The timeline of every time-varying entity: simulated time since reset (s).
TIMELINE = "sim_time"

#: The fixed entity paths of a recording (per estimator ``<name>`` paths come in addition).
ENTITIES: tuple[str, ...] = (
    "world/deck",
    "world/deck/plate",
    "world/deck/tag",
    "world/drone",
    "world/drone/body",
    "world/drone/tof",
    "world/drone/camera",
    "world/trajectory",
    "camera/frame",
    "camera/corners",
    "camera/tag",
    "truth/position",
    "truth/euler",
    "tof/ranges",
    "tof/valid",
    "action",
    "reward/total",
    "wind",
    "faults/frame_lost",
    "faults/dead_beams",
    "events/tag",
    "events/outcome",
)

#: JPEG quality of the recorded camera images (rendered camera model).
JPEG_QUALITY = 85

#: Length (m) of the stub drawn for an invalid ToF beam.
INVALID_BEAM = 0.25

_GREEN = (40, 200, 80)
_RED = (230, 40, 40)
_ESTIMATE_COLORS = ((240, 160, 30), (60, 140, 255), (200, 60, 220), (0, 200, 200), (150, 150, 150))


@dataclass(frozen=True)
class SceneGeometry:
    """The fixed geometry a recording draws (m, px, body frame).

    Attributes:
        deck_size, deck_thickness, tag_size: the deck plate's edge and thickness, the tag's edge (m).
        tof_positions: (4, 3) ToF sensor positions in the body frame (m).
        camera_position: (3,) optical centre in the body frame (m).
        K: (3, 3) camera intrinsics, or None (no camera drawn).
        image_size: (width, height) px, or None.
        max_range: the ToF's maximum range (m); an invalid beam is drawn as a short red stub of at
            most :data:`INVALID_BEAM` m.
    """

    deck_size: float
    deck_thickness: float
    tag_size: float
    tof_positions: NDArray[np.float64]
    camera_position: NDArray[np.float64]
    K: NDArray[np.float64] | None
    image_size: tuple[int, int] | None
    max_range: float


def _angle_error(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Per-axis angle difference wrapped to (-pi, pi] (rad)."""
    d = np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64)
    return np.asarray((d + math.pi) % (2 * math.pi) - math.pi)


@dataclass
class _Series:
    """Rows of one entity: times (s) and values."""

    times: list[float] = field(default_factory=list)
    rows: list[Any] = field(default_factory=list)

    def add(self, t: float, row: Any) -> None:
        self.times.append(t)
        self.rows.append(row)


class EpisodeLog:
    """One episode's values, gathered per step (:meth:`add_step`) and sent at its end (:meth:`send`).

    Args:
        geometry: the scene's fixed geometry.
        estimator_names: the estimators whose estimates are recorded (in order).
    """

    def __init__(self, geometry: SceneGeometry, estimator_names: Sequence[str] = ()) -> None:
        self.geometry = geometry
        self.estimator_names = tuple(estimator_names)
        self.series: dict[str, _Series] = {}
        self.images: list[tuple[float, NDArray[np.uint8]]] = []
        self.texts: list[tuple[float, str, str, str]] = []  # time, path, text, level
        self._last_text: dict[str, str] = {}
        self.positions: list[NDArray[np.float64]] = []
        self.steps = 0
        self.end_time = 0.0

    def _add(self, path: str, t: float, row: Any) -> None:
        s = self.series.get(path)
        if s is None:
            s = self.series[path] = _Series()
        s.add(t, row)

    def _text_on_change(self, path: str, t: float, text: str, level: str = "INFO") -> None:
        if self._last_text.get(path) != text:
            self._last_text[path] = text
            self.texts.append((t, path, text, level))

    def add_step(
        self,
        info: Mapping[str, Any],
        *,
        action: Any = None,
        reward: float | None = None,
        frame: Any = None,
        estimates: Mapping[str, Any] | None = None,
    ) -> None:
        """Record one instant: the env's ``info`` (ground truth, reward terms, wind, outcome),
        the ``action`` and ``reward`` of the step (None at reset), the estimators' sensor
        ``frame`` (a :class:`~ihrcf_env.core.estimators.SensorFrame`, or None) and their
        ``estimates`` (name -> :class:`~ihrcf_env.core.estimators.PoseEstimate`, or None)."""
        t = float(info.get("time", math.nan))
        if not math.isfinite(t):
            t = self.end_time
        self.end_time = t
        self.steps += 1
        if "drone_position_world" in info:
            p = np.asarray(info["drone_position_world"], dtype=np.float64)
            q = np.asarray(info.get("drone_quaternion_world", (0.0, 0.0, 0.0, 1.0)), dtype=np.float64)
            self._add("world/drone", t, (p, q))
            self.positions.append(p)
        if "deck_position_world" in info:
            p = np.asarray(info["deck_position_world"], dtype=np.float64)
            q = np.asarray(info.get("deck_quaternion_world", (0.0, 0.0, 0.0, 1.0)), dtype=np.float64)
            self._add("world/deck", t, (p, q))
        truth_p = truth_e = None
        if "deck_position_body" in info and "deck_euler_body" in info:
            truth_p = np.asarray(info["deck_position_body"], dtype=np.float64)
            truth_e = np.asarray(info["deck_euler_body"], dtype=np.float64)
            self._add("truth/position", t, truth_p)
            self._add("truth/euler", t, truth_e)
        if "wind_velocity" in info:
            self._add("wind", t, np.asarray(info["wind_velocity"], dtype=np.float64))
        for key, value in info.items():
            if key.startswith("reward_") and isinstance(value, int | float):
                self._add(f"reward/{key.removeprefix('reward_')}", t, float(value))
        if reward is not None:
            self._add("reward/total", t, float(reward))
        if action is not None:
            a = np.asarray(action, dtype=np.float64).reshape(-1)
            if a.size and np.all(np.isfinite(a)):
                self._add("action", t, a)
        reason = info.get("tag_reason")
        if isinstance(reason, str):
            self._add("faults/frame_lost", t, float("lost" in reason))
            self._text_on_change("events/tag", t, f"tag: {reason or 'detected'}", "DEBUG")
        if frame is not None:
            self._add_frame(t, frame)
        for name in self.estimator_names:
            est = None if estimates is None else estimates.get(name)
            if est is None:
                continue
            self._add(f"estimates/{name}/valid", t, float(est.valid))
            self._text_on_change(f"estimates/{name}/reason", t, est.reason or "valid")
            if est.valid:
                pos = np.asarray(est.position, dtype=np.float64)
                eul = np.asarray(est.euler, dtype=np.float64)
                self._add(f"estimates/{name}/position", t, pos)
                self._add(f"estimates/{name}/euler", t, eul)
                self._add(f"estimates/{name}/residual", t, float(est.residual))
                self._add(f"world/drone/estimates/{name}", t, (pos, np.asarray(est.rotation)))
                if truth_p is not None and truth_e is not None:
                    self._add(f"estimates/{name}/position_error", t, float(np.linalg.norm(pos - truth_p)))
                    self._add(f"estimates/{name}/angle_error", t, _angle_error(eul, truth_e))

    def end(self, info: Mapping[str, Any], ended: bool = True) -> None:
        """The outcome and touchdown figures of the episode's last ``info`` as an event;
        ``ended`` False: the episode was cut short (reset or closed while flying)."""
        t = self.end_time
        outcome = info.get("outcome", "flying")
        if outcome == "flying":
            outcome = "timeout" if ended else "stopped"
        text = f"outcome: {outcome}"
        if info.get("crash_reason"):
            text += f" ({info['crash_reason']})"
        td = info.get("touchdown")
        if isinstance(td, Mapping):
            figures = []
            if "relative_vertical_speed" in td:
                figures.append(f"speed {abs(float(td['relative_vertical_speed'])):.3f} m/s")
            if "relative_tilt" in td:
                figures.append(f"tilt {math.degrees(float(td['relative_tilt'])):.2f} deg")
            if "tag_offset" in info:
                figures.append(f"offset {float(info['tag_offset']):.3f} m")
            text += "; touchdown " + ", ".join(figures)
        self._text_on_change("events/outcome", t, text, "INFO" if outcome == "success" else "WARN")

    def _add_frame(self, t: float, frame: Any) -> None:
        ranges = np.asarray(frame.ranges, dtype=np.float64).reshape(-1)
        valid = np.asarray(frame.ranges_valid, dtype=bool).reshape(-1)
        finite = np.where(np.isfinite(ranges), ranges, 0.0)
        self._add("tof/ranges", t, finite)
        self._add("tof/valid", t, valid.astype(np.float64))
        self._add("faults/dead_beams", t, float(np.count_nonzero(~valid)))
        self._add("world/drone/tof", t, (finite, valid))
        corners = frame.corners
        self._add("camera/corners", t, None if corners is None else np.asarray(corners, dtype=np.float64))
        image = getattr(frame, "image", None)
        if image is not None:
            self.images.append((t, np.asarray(image)))

    # ------------------------------------------------------------------ sending

    def send(self, rec: Any, rr: ModuleType) -> None:
        """Write everything gathered to the recording stream ``rec`` (module ``rr``: rerun)."""
        g = self.geometry
        rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        rec.log(
            "world/deck/plate",
            rr.Boxes3D(
                centers=[[0.0, 0.0, -g.deck_thickness / 2]],
                sizes=[[g.deck_size, g.deck_size, g.deck_thickness]],
                colors=[(190, 190, 200)],
                fill_mode="solid",
            ),
            static=True,
        )
        rec.log(
            "world/deck/tag",
            rr.Boxes3D(
                centers=[[0.0, 0.0, 0.001]],
                sizes=[[g.tag_size, g.tag_size, 0.002]],
                colors=[(20, 20, 20)],
                fill_mode="solid",
                labels=["tag"],
            ),
            static=True,
        )
        rec.log(
            "world/drone/body",
            rr.Boxes3D(sizes=[[0.3, 0.3, 0.06]], colors=[(80, 120, 240)], labels=["drone"]),
            static=True,
        )
        if g.K is not None and g.image_size is not None:
            rec.log(
                "world/drone/camera",
                rr.Transform3D(translation=g.camera_position, mat3x3=R_BODY_CAM),
                rr.Pinhole(image_from_camera=g.K, resolution=list(g.image_size), image_plane_distance=0.1),
                static=True,
            )
            w, h = g.image_size
            rec.log(
                "camera/frame",
                rr.LineStrips2D([[[0, 0], [w, 0], [w, h], [0, h], [0, 0]]], colors=[(120, 120, 120)]),
                static=True,
            )
        rec.log("camera/corners", rr.Points2D.from_fields(radii=3.0, colors=[_GREEN]), static=True)
        rec.log("camera/tag", rr.LineStrips2D.from_fields(colors=[_GREEN]), static=True)
        for i, name in enumerate(self.estimator_names):
            color = _ESTIMATE_COLORS[i % len(_ESTIMATE_COLORS)]
            rec.log(
                f"world/drone/estimates/{name}",
                rr.Boxes3D(sizes=[[g.tag_size, g.tag_size, 0.004]], colors=[color], labels=[name]),
                static=True,
            )
        for path, s in self.series.items():
            self._send_series(rec, rr, path, s)
        if self.positions:
            rec.set_time(TIMELINE, duration=0.0)
            rec.log(
                "world/trajectory", rr.LineStrips3D([np.asarray(self.positions)], colors=[(80, 120, 240)])
            )
        for t, image in self.images:
            rec.set_time(TIMELINE, duration=t)
            rec.log("camera/image", rr.Image(image).compress(jpeg_quality=JPEG_QUALITY))
        for t, path, text, level in self.texts:
            rec.set_time(TIMELINE, duration=t)
            rec.log(path, rr.TextLog(text, level=level))
        rec.send_blueprint(blueprint(rr, self.estimator_names))

    def _send_series(self, rec: Any, rr: ModuleType, path: str, s: _Series) -> None:
        index = [rr.TimeColumn(TIMELINE, duration=np.asarray(s.times, dtype=np.float64))]
        if path in ("world/drone", "world/deck"):
            p = np.array([r[0] for r in s.rows])
            q = np.array([r[1] for r in s.rows])
            rec.send_columns(path, indexes=index, columns=rr.Transform3D.columns(translation=p, quaternion=q))
        elif path.startswith("world/drone/estimates/"):
            p = np.array([r[0] for r in s.rows])
            m = np.array([r[1] for r in s.rows])
            rec.send_columns(path, indexes=index, columns=rr.Transform3D.columns(translation=p, mat3x3=m))
        elif path == "world/drone/tof":
            self._send_beams(rec, rr, index, s)
        elif path == "camera/corners":
            self._send_corners(rec, rr, index, s)
        else:
            values = np.array(s.rows, dtype=np.float64)
            rec.send_columns(path, indexes=index, columns=rr.Scalars.columns(scalars=values))

    def _send_beams(self, rec: Any, rr: ModuleType, index: list[Any], s: _Series) -> None:
        g = self.geometry
        axis = R_BODY_CAM[:, 2]  # the optical axis in the body frame (down)
        strips, colors = [], []
        for ranges, valid in s.rows:
            for k in range(len(ranges)):
                length = ranges[k] if valid[k] else min(g.max_range, INVALID_BEAM)
                start = g.tof_positions[k]
                strips.append([start, start + length * axis])
                colors.append(_GREEN if valid[k] else _RED)
        n = len(s.rows[0][0])
        rec.send_columns(
            "world/drone/tof",
            indexes=index,
            columns=rr.LineStrips3D.columns(strips=strips, colors=colors).partition([n] * len(s.rows)),
        )

    def _send_corners(self, rec: Any, rr: ModuleType, index: list[Any], s: _Series) -> None:
        """The detected corners and their outline, as columns (an empty row: not detected)."""
        points = [c for c in s.rows if c is not None]
        counts = [0 if c is None else len(c) for c in s.rows]
        flat = np.vstack(points) if points else np.zeros((0, 2))
        rec.send_columns(
            "camera/corners",
            indexes=index,
            columns=rr.Points2D.columns(positions=flat).partition(counts),
        )
        outlines = [np.vstack([c, c[:1]]) for c in points]
        rec.send_columns(
            "camera/tag",
            indexes=index,
            columns=rr.LineStrips2D.columns(strips=outlines).partition([int(n > 0) for n in counts]),
        )


def blueprint(rr: ModuleType, estimator_names: Sequence[str]) -> Any:
    """The default layout: the 3D scene, the camera, the estimate errors and the truth beside each
    estimate's position; it opens at the episode's end (the outcome), to be scrubbed back."""
    rrb = rr.blueprint
    errors = [f"/estimates/{n}/position_error" for n in estimator_names]
    angles = [f"/estimates/{n}/angle_error" for n in estimator_names]
    heights = ["/truth/position", *(f"/estimates/{n}/position" for n in estimator_names)]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(name="scene", origin="/world"),
            rrb.Vertical(
                rrb.Spatial2DView(name="camera", origin="/camera"),
                rrb.TimeSeriesView(name="position error (m)", contents=errors or ["/estimates/**"]),
                rrb.TimeSeriesView(name="angle error (rad)", contents=angles or ["/estimates/**"]),
                rrb.TimeSeriesView(name="deck position, body frame (m)", contents=heights),
                rrb.TextLogView(name="events", origin="/events"),
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE, play_state="following", state="collapsed"),
        collapse_panels=True,
    )
