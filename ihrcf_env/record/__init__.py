"""Rerun recordings of landing and hover episodes (the optional ``[viewer]`` extra: ``rerun-sdk``).

:class:`RecordEpisode` wraps an env in a user's own loop; :func:`record_failures` wraps one to
record its failed episodes into a folder. The commands ``ihrcf-record`` and ``ihrcf-evaluate
--record DIR`` (:mod:`ihrcf_env.record.command`, :mod:`ihrcf_env.cli.evaluate`) use them; the
package imports nothing of :mod:`ihrcf_env.cli`, and importing it does not load its command. The
package imports without Rerun; asking for a recording without it raises :class:`RerunMissingError`
saying how to install it. What a recording holds: :mod:`ihrcf_env.record.episode_log`.
"""

from ihrcf_env.record._rerun import INSTALL_HINT, RerunMissingError, import_rerun
from ihrcf_env.record.episode_log import ENTITIES, TIMELINE, EpisodeLog, SceneGeometry
from ihrcf_env.record.wrapper import (
    VIEWER_PORT,
    RecordEpisode,
    RecordingPathError,
    RecordingWriteError,
    ViewerMissingError,
    check_record_dir,
    check_recording_path,
    check_viewer,
    find_viewer,
    record_failures,
    scene_geometry,
)

__all__ = [
    "ENTITIES",
    "INSTALL_HINT",
    "TIMELINE",
    "VIEWER_PORT",
    "EpisodeLog",
    "RecordEpisode",
    "RecordingPathError",
    "RecordingWriteError",
    "RerunMissingError",
    "SceneGeometry",
    "ViewerMissingError",
    "check_record_dir",
    "check_recording_path",
    "check_viewer",
    "find_viewer",
    "import_rerun",
    "record_failures",
    "scene_geometry",
]
