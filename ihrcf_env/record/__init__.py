"""Rerun recordings of landing and hover episodes (the optional ``[viewer]`` extra: ``rerun-sdk``).

:class:`RecordEpisode` wraps an env in a user's own loop; ``ihrcf-record`` (``python -m
ihrcf_env.record``) flies one episode with any policy ``ihrcf-evaluate`` accepts and records it;
``ihrcf-evaluate --record DIR`` records its failed episodes. The package imports without Rerun;
asking for a recording without it raises :class:`RerunMissingError` saying how to install it.
What a recording holds: :mod:`ihrcf_env.record.episode_log`.
"""

from typing import Any

from ihrcf_env.record._rerun import INSTALL_HINT, RerunMissingError
from ihrcf_env.record.episode_log import ENTITIES, TIMELINE, EpisodeLog, SceneGeometry
from ihrcf_env.record.wrapper import RecordEpisode, RecordingPathError, check_recording_path, scene_geometry

__all__ = [
    "ENTITIES",
    "INSTALL_HINT",
    "TIMELINE",
    "EpisodeLog",
    "RecordEpisode",
    "RecordingPathError",
    "RerunMissingError",
    "SceneGeometry",
    "check_recording_path",
    "scene_geometry",
]


def __getattr__(name: str) -> Any:
    if name == "main":  # the command (``python -m ihrcf_env.record``), imported only when asked for
        from ihrcf_env.cli.record import main

        return main
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
