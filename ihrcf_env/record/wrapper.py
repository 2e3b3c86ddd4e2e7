""":class:`RecordEpisode`: a Gymnasium wrapper that writes each episode as a Rerun recording."""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import stat
import sys
import tempfile
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import gymnasium as gym
import numpy as np

from ihrcf_env.record._rerun import import_rerun
from ihrcf_env.record.episode_log import EpisodeLog, SceneGeometry
from ihrcf_env.wrappers.estimates import base_config

__all__ = [
    "VIEWER_PORT",
    "RecordEpisode",
    "RecordingPathError",
    "RecordingWriteError",
    "ViewerMissingError",
    "check_record_dir",
    "check_recording_path",
    "check_viewer",
    "find_viewer",
    "record_failures",
    "scene_geometry",
]

#: The suffix of a Rerun recording: an existing file is replaced only if its name ends so.
SUFFIX = ".rrd"
#: The port a Rerun viewer listens on (``rerun``'s default): a running viewer is used as it is.
VIEWER_PORT = 9876


class RecordingPathError(ValueError):
    """A recording's output path is a folder, an existing file that is not a recording, a special
    file (a device, a FIFO, a socket), or cannot be written."""


class RecordingWriteError(OSError):
    """Writing a recording failed (e.g. the disk is full); the message names the file."""


class ViewerMissingError(FileNotFoundError):
    """``spawn=True`` and no Rerun viewer can be started: no ``rerun`` executable on ``PATH`` or
    beside the Python interpreter, and none listening on :data:`VIEWER_PORT`."""


def _check_existing(out: Path) -> None:
    """RecordingPathError if ``out`` exists and may not be replaced: a folder, a special file
    (device, FIFO, socket; a symbolic link to one too), or a file whose name does not end in
    ``.rrd``. A missing path passes."""
    try:
        st = out.stat()  # follows a symbolic link: what the user named is what it points to
    except FileNotFoundError:
        if out.is_symlink():
            raise RecordingPathError(f"recording path {str(out)!r} is a broken symbolic link") from None
        return
    except OSError as e:
        raise RecordingPathError(f"cannot use the recording path {str(out)!r} ({e.strerror or e})") from None
    if stat.S_ISDIR(st.st_mode):
        raise RecordingPathError(f"recording path {str(out)!r} is a folder; give a file name ({SUFFIX})")
    if not stat.S_ISREG(st.st_mode):
        raise RecordingPathError(
            f"recording path {str(out)!r} exists and is not a regular file (a device, FIFO or socket); "
            "give a file name"
        )
    if out.suffix != SUFFIX:
        raise RecordingPathError(
            f"recording path {str(out)!r} exists and is not a recording ({SUFFIX}); not replacing it"
        )


def check_recording_path(path: str | os.PathLike[str]) -> Path:
    """``path`` as a file a recording may be written to, or :class:`RecordingPathError`: not
    empty, not a folder, not an existing special file (device, FIFO, socket) or an existing file
    whose name does not end in ``.rrd`` (only a recording is replaced), and a file can be created
    in its folder (or its nearest existing ancestor, the missing folders being made when
    writing)."""
    if isinstance(path, bool) or not isinstance(path, str | os.PathLike):
        raise TypeError(f"path must be a str or os.PathLike (a .rrd file), got {type(path).__name__}")
    if not os.fspath(path).strip():
        raise RecordingPathError("recording path is empty; give a file name (.rrd)")
    out = Path(path)
    _check_existing(out)
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


def check_record_dir(directory: str | os.PathLike[str]) -> Path:
    """``directory`` as a folder recordings may be written into (made when writing), or
    :class:`RecordingPathError`: not empty, not an existing file, and writable."""
    if isinstance(directory, bool) or not isinstance(directory, str | os.PathLike):
        raise TypeError(f"directory must be a str or os.PathLike, got {type(directory).__name__}")
    if not os.fspath(directory).strip():
        raise RecordingPathError("recording folder is empty; give a folder name")
    out = Path(directory)
    if out.exists() and not out.is_dir():
        raise RecordingPathError(f"{str(out)!r} is not a folder")
    check_recording_path(out / f"probe{SUFFIX}")
    return out


def find_viewer() -> str | None:
    """The Rerun viewer executable ``rerun``: on ``PATH``, else beside the running Python (the
    ``bin`` folder of a virtual environment not activated); None if neither has it."""
    found = shutil.which("rerun")
    if found is not None:
        return found
    beside = Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    return str(beside) if beside.is_file() and os.access(beside, os.X_OK) else None


def _viewer_listening(port: int = VIEWER_PORT) -> bool:
    """Whether something accepts connections on the viewer's port of this machine."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.2):
            return True
    except OSError:
        return False


def check_viewer() -> str | None:
    """The viewer executable :func:`find_viewer` finds, or None when a viewer already listens on
    :data:`VIEWER_PORT`; :class:`ViewerMissingError` if neither."""
    found = find_viewer()
    if found is None and not _viewer_listening():
        raise ViewerMissingError(
            "spawn needs the Rerun viewer: no 'rerun' executable on PATH (it comes with "
            '"ihrcf-env[viewer]"), and no viewer listening on port '
            f"{VIEWER_PORT}; write a file instead, or put the viewer on PATH"
        )
    return found


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
        path: the ``.rrd`` file of each episode (a str or os.PathLike); ``{seed}`` and ``{episode}``
            (0-based count) in it are filled in at each reset; an unseeded reset fills ``{seed}``
            with ``none``, so a format spec (``{seed:05d}``) is refused here. A path without them
            is overwritten by each episode: only the last one is kept (a UserWarning says so the
            first time). An existing file is replaced only if its name ends in ``.rrd``. None
            with ``spawn=True``.
        spawn: send each episode to a Rerun viewer (started if none runs) instead of a file.
        keep: a callable given an episode's last ``info`` that returns whether to write it (a
            bool); None (default): every episode.
        enabled: False: the wrapper passes every call through and records nothing.
        application_id: the Rerun application id of the recordings.

    Raises:
        RerunMissingError: (an ImportError) enabled and the Rerun SDK is not installed.
        RecordingPathError: ``path`` is a folder, a special file, an existing file that is not a
            ``.rrd``, a template that cannot be filled in, or its folder cannot be written.
        ViewerMissingError: ``spawn=True`` and no Rerun viewer can be started.
        TypeError: ``path`` is not a str / os.PathLike / None, ``keep`` is not callable / None.

    Writing a recording that fails (e.g. a full disk) raises :class:`RecordingWriteError` (an
    OSError) naming the file; ``keep`` returning something other than a bool raises TypeError.

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
        if path is not None and (isinstance(path, bool) or not isinstance(path, str | os.PathLike)):
            raise TypeError(f"path must be a str or os.PathLike (a .rrd file) or None, got {path!r}")
        if keep is not None and not callable(keep):
            raise TypeError(f"keep must be a callable (info -> bool) or None, got {keep!r}")
        self.enabled = bool(enabled)
        self.spawn = bool(spawn)
        self.keep = keep
        self.application_id = str(application_id)
        self.written: list[Path] = []
        self._warned_overwrite = False
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
            for seed in (0, None):  # a seeded and an unseeded episode
                check_recording_path(self._path_of(0, seed))
        self._viewer = check_viewer() if self._template is None else None
        self._geometry = scene_geometry(env)
        stage = _stage(env)
        self._names: tuple[str, ...] = tuple(getattr(stage, "sources", {}) or ())

    def _path_of(self, episode: int, seed: int | None) -> Path:
        assert self._template is not None
        try:
            text = self._template.format(episode=episode, seed="none" if seed is None else seed)
        except (KeyError, IndexError, ValueError, AttributeError) as e:
            what = "an unseeded episode (its {seed} reads 'none')" if seed is None else "an episode"
            raise RecordingPathError(
                f"recording path {self._template!r}: cannot be filled in for {what}: only {{seed}} "
                f"and {{episode}} may be filled in, and {{seed}} takes no format spec ({e})"
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
        if log is None:
            return
        if self.keep is not None:
            wanted = self.keep(self._info)
            if not isinstance(wanted, bool | np.bool_):
                raise TypeError(f"keep must return a bool (write the episode or not), got {wanted!r}")
            if not wanted:
                return
        log.end(self._info, ended)
        rr = self._rr
        name = f"episode {self._episode}" + ("" if self._seed is None else f", seed {self._seed}")
        rec = rr.RecordingStream(self.application_id)
        if self._template is None:
            rr.spawn(recording=rec, executable_path=self._viewer, default_blueprint=None)
            rec.send_recording_name(name)
            log.send(rec, rr)
            rec.flush()
            return
        out = self._path_of(self._episode, self._seed)
        _check_existing(out)  # checked again: the file may have appeared since the reset
        if out in self.written and not self._warned_overwrite:
            self._warned_overwrite = True
            warnings.warn(
                f"recording path {str(out)!r}: episode {self._episode} replaces an earlier episode's "
                "recording (put {episode} or {seed} in the path to keep each one)",
                UserWarning,
                stacklevel=3,
            )
        target = Path(os.path.realpath(out))  # a symbolic link to a recording stays a link
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
        except OSError as e:
            raise RecordingWriteError(
                e.errno, f"cannot write the recording {str(out)!r} ({e.strerror or e})"
            ) from e
        os.close(fd)
        try:
            os.chmod(tmp, _file_mode(target))
            rec.save(tmp)
            rec.send_recording_name(name)
            log.send(rec, rr)
            try:
                rec.flush()
            except (RuntimeError, OSError) as e:  # Rerun's file writer stopped: a full disk, a quota
                raise RecordingWriteError(
                    f"writing the recording {str(out)!r} failed (is the disk full?): {e}"
                ) from e
            rec.disconnect()
            os.replace(tmp, target)
        except BaseException:
            with contextlib.suppress(Exception):
                rec.disconnect()
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
        self.written.append(out)


def _file_stem(env_id: str) -> str:
    """The file-name part of an env id (``ns/Name-v2`` -> ``Name-v2``), other characters as ``_``."""
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in env_id.rpartition("/")[2])


def record_failures(
    env: gym.Env, directory: str | os.PathLike[str], env_id: str, record_all: bool = False
) -> RecordEpisode:
    """``env`` wrapped to record each failed episode (outcome not ``"success"``; each episode with
    ``record_all``) as ``DIR/<env name>-seed<seed>.rrd``. Raises as :class:`RecordEpisode` does."""

    def keep(info: Mapping[str, Any]) -> bool:
        return bool(record_all) or info.get("outcome") != "success"

    folder = check_record_dir(directory)
    return RecordEpisode(env, folder / f"{_file_stem(env_id)}-seed{{seed}}.rrd", keep=keep)
