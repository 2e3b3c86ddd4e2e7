""":class:`RecordEpisode`: a Gymnasium wrapper that writes each episode as a Rerun recording."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Callable, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.record._rerun import import_rerun
from ihrcf_env.record.episode_log import EpisodeLog, SceneGeometry
from ihrcf_env.wrappers.estimates import base_config

__all__ = ["RecordEpisode", "RecordingPathError", "check_recording_path", "scene_geometry"]


class RecordingPathError(ValueError):
    """A recording's output path is a folder or cannot be written."""


def check_recording_path(path: str | os.PathLike[str]) -> Path:
    """``path`` as a file a recording may be written to, or :class:`RecordingPathError`: not a
    folder, and a file can be created in its folder (or its nearest existing ancestor, the
    missing folders being made when writing)."""
    out = Path(path)
    if out.is_dir():
        raise RecordingPathError(f"recording path {str(out)!r} is a folder; give a file name (.rrd)")
    parent = out.parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise RecordingPathError(f"cannot write the recording {str(out)!r}: {str(parent)!r} is not a folder")
    try:
        with tempfile.NamedTemporaryFile(dir=parent, prefix=f".{out.name}.", suffix=".probe"):
            pass
    except OSError as e:
        raise RecordingPathError(f"cannot write the recording {str(out)!r} ({e.strerror or e})") from None
    return out


def _file_mode(path: Path) -> int:
    """The mode a plain ``open(path, "w")`` gives: an existing file's, else 0o666 less the umask."""
    try:
        return path.stat().st_mode & 0o777
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


def _stage(env: gym.Env) -> Any:
    """The estimator stage of a wrapped landing env (its public ``stage``), or None."""
    try:
        return env.get_wrapper_attr("stage")
    except AttributeError:
        return None


def _raw_frame(obs: Any) -> SimpleNamespace | None:
    """The sensor readings of a raw deck env's observation (no estimator stage): ranges, valid
    flags, the tag corners when detected and the image when present; None for another observation."""
    if not isinstance(obs, Mapping) or "ranges" not in obs or "ranges_valid" not in obs:
        return None
    detected = bool(obs.get("tag_detected", False)) and "tag_corners" in obs
    return SimpleNamespace(
        ranges=obs["ranges"],
        ranges_valid=obs["ranges_valid"],
        corners=np.asarray(obs["tag_corners"], dtype=np.float64) if detected else None,
        image=obs.get("image"),
    )


def scene_geometry(env: gym.Env) -> SceneGeometry:
    """The fixed geometry of a (wrapped) deck env: deck, tag, ToF rig and camera."""
    world = base_config(env).world
    stage = _stage(env)
    cal = getattr(stage, "calibration", None)
    K = None if cal is None else np.asarray(cal.K, dtype=np.float64)
    size = None if cal is None else (int(cal.image_width), int(cal.image_height))
    return SceneGeometry(
        deck_size=float(world.deck.size),
        deck_thickness=float(world.deck.thickness),
        tag_size=float(world.deck.tag_size),
        tof_positions=np.asarray(world.rig.sensor_positions_body, dtype=np.float64),
        camera_position=np.asarray(world.rig.camera_position, dtype=np.float64),
        K=K,
        image_size=size,
        max_range=float(world.tof.max_range),
    )


class RecordEpisode(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Records each episode of a deck env as a Rerun recording (``.rrd`` file or a viewer).

    The values are gathered as the episode runs (ground truth, reward terms, wind and outcome from
    ``info``; the camera frame, ToF ranges and each estimator's pose from the landing wrapper's
    public ``stage``, or the readings of a raw env's Dict observation) and written when the
    episode ends (terminated or truncated), when the env is reset before that, or on
    :meth:`close`; see :mod:`ihrcf_env.record.episode_log` for the
    entities. A file is written whole or not at all.

    Args:
        env: a deck-landing env (e.g. ``gym.make("ihrcf_env/DeckLanding-v2")``), possibly wrapped.
        path: the ``.rrd`` file of each episode; ``{seed}`` and ``{episode}`` (0-based count) in it
            are filled in at each reset (a fixed path is overwritten by each episode). None with
            ``spawn=True``.
        spawn: send each episode to a Rerun viewer (started if none runs) instead of a file.
        keep: given an episode's last ``info``, whether to write it (default: every episode).
        enabled: False: the wrapper passes every call through and records nothing.
        application_id: the Rerun application id of the recordings.

    Raises:
        RerunMissingError: (an ImportError) enabled and the Rerun SDK is not installed.
        RecordingPathError: ``path`` is a folder or its folder cannot be written.

    Attributes:
        written: the paths of the recordings written so far (files only).
    """

    def __init__(
        self,
        env: gym.Env,
        path: str | os.PathLike[str] | None = None,
        *,
        spawn: bool = False,
        keep: Callable[[Mapping[str, Any]], bool] | None = None,
        enabled: bool = True,
        application_id: str = "ihrcf_env",
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(
            self, path=path, spawn=spawn, enabled=enabled, application_id=application_id
        )
        gym.Wrapper.__init__(self, env)
        self.enabled = bool(enabled)
        self.spawn = bool(spawn)
        self.keep = keep
        self.application_id = str(application_id)
        self.written: list[Path] = []
        self._template = None if path is None else os.fspath(path)
        self._log: EpisodeLog | None = None
        self._info: Mapping[str, Any] = {}
        self._episode = -1
        self._seed: int | None = None
        if not self.enabled:
            return
        self._rr = import_rerun()
        if self._template is None and not self.spawn:
            raise RecordingPathError("give a recording path (.rrd) or spawn=True")
        if self._template is not None:
            check_recording_path(self._path_of(0, 0))
        self._geometry = scene_geometry(env)
        stage = _stage(env)
        self._names: tuple[str, ...] = tuple(getattr(stage, "sources", {}) or ())

    def _path_of(self, episode: int, seed: int | None) -> Path:
        assert self._template is not None
        try:
            text = self._template.format(episode=episode, seed="none" if seed is None else seed)
        except (KeyError, IndexError, ValueError) as e:
            raise RecordingPathError(
                f"recording path {self._template!r}: only {{seed}} and {{episode}} may be filled in ({e})"
            ) from None
        return Path(text)

    def _observe(
        self, obs: Any, info: Mapping[str, Any], action: Any = None, reward: float | None = None
    ) -> None:
        assert self._log is not None
        stage = _stage(self.env)
        frame = getattr(stage, "last_frame", None) if stage is not None else _raw_frame(obs)
        self._log.add_step(
            info,
            action=action,
            reward=reward,
            frame=frame,
            estimates=getattr(stage, "last_estimates", None),
        )
        self._info = info

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        if not self.enabled:
            return self.env.reset(seed=seed, options=options)
        self._finish()
        obs, info = self.env.reset(seed=seed, options=options)
        self._episode += 1
        self._seed = seed
        self._log = EpisodeLog(self._geometry, self._names)
        self._observe(obs, info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict]:
        if not self.enabled:
            return self.env.step(action)
        obs, reward, terminated, truncated, info = self.env.step(action)
        if self._log is not None:
            self._observe(obs, info, action, float(reward))
            if terminated or truncated:
                self._finish(ended=True)
        return obs, reward, terminated, truncated, info

    def close(self) -> None:
        try:
            if self.enabled:
                self._finish()
        finally:
            super().close()

    def _finish(self, ended: bool = False) -> None:
        """Write the episode gathered so far (if any, and if ``keep`` wants it); ``ended``: it
        terminated or was truncated."""
        log, self._log = self._log, None
        if log is None or (self.keep is not None and not self.keep(self._info)):
            return
        log.end(self._info, ended)
        rr = self._rr
        name = f"episode {self._episode}" + ("" if self._seed is None else f", seed {self._seed}")
        rec = rr.RecordingStream(self.application_id)
        if self._template is None:
            rec.spawn(default_blueprint=None)
            rec.send_recording_name(name)
            log.send(rec, rr)
            rec.flush()
            return
        out = self._path_of(self._episode, self._seed)
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp")
        os.close(fd)
        try:
            os.chmod(tmp, _file_mode(out))
            rec.save(tmp)
            rec.send_recording_name(name)
            log.send(rec, rr)
            rec.flush()
            rec.disconnect()
            os.replace(tmp, out)
        except BaseException:
            with contextlib.suppress(Exception):
                rec.disconnect()
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        self.written.append(out)
