"""The observation and info keys the envs and their wrappers write themselves.

User components add keys beside them: a registered sensor's outputs become observation keys, a
registered estimator's name becomes ``obs[name]`` (and a block of the flat observation) and
``info[f"{name}{suffix}"]`` for each suffix of :data:`ESTIMATOR_INFO_SUFFIXES`. The names here are
refused for them at registration, so a user component never overwrites what the env writes
(``tests/envs/test_hostile_input.py`` checks these sets cover every key the envs write).
"""

from __future__ import annotations

__all__ = [
    "ESTIMATOR_INFO_SUFFIXES",
    "FLAT_KEYS",
    "INFO_KEYS",
    "OBSERVATION_KEYS",
    "env_key_reason",
    "estimator_name_reason",
    "reserved_estimator_names",
]

#: Keys of the dict observation the envs and the estimate wrapper write (the raw sensors, the
#: sample ages, ground truth and the fused filter's deck motion).
OBSERVATION_KEYS: frozenset[str] = frozenset(
    {
        "image",
        "tag_corners",
        "tag_detected",
        "tag_status",
        "camera_age",
        "camera_frame",
        "tof_age",
        "imu_age",
        "ranges",
        "ranges_valid",
        "imu",
        "nav_velocity",
        "ground_truth",
        "motion",
    }
)
#: Keys of ``info`` the envs write (state, timing, outcome, reward terms).
INFO_KEYS: frozenset[str] = frozenset(
    {
        "time",
        "camera_time",
        "camera_age",
        "tag_reason",
        "tag_offset",
        "deck_position_body",
        "deck_euler_body",
        "deck_rotation_body",
        "drone_position_world",
        "drone_quaternion_world",
        "deck_position_world",
        "deck_quaternion_world",
        "leg_lengths",
        "contact_deck",
        "contact_ground",
        "wind_velocity",
        "relative_velocity",
        "outcome",
        "crash_reason",
        "touchdown",
        "is_success",
        "reward_position",
        "reward_velocity",
        "reward_attitude",
        "reward_action",
        "reward_terminal",
        "reward_progress",
        "reward_time",
    }
)
#: Named slices of the flat observation besides the fields (the whole vector).
FLAT_KEYS: frozenset[str] = frozenset({"all"})
#: ``info[f"{name}{suffix}"]`` an estimator ``name`` writes: why it is invalid, its fit residual,
#: the age of its values.
ESTIMATOR_INFO_SUFFIXES: tuple[str, ...] = ("_reason", "_residual", "_age")


def _prefixes(keys: frozenset[str]) -> dict[str, str]:
    """Name -> the key ``f"{name}{suffix}"`` among ``keys`` for an estimator suffix."""
    out: dict[str, str] = {}
    for key in sorted(keys):
        for suffix in ESTIMATOR_INFO_SUFFIXES:
            if key.endswith(suffix) and len(key) > len(suffix):
                out.setdefault(key[: -len(suffix)], key)
    return out


def env_key_reason(name: str) -> str | None:
    """Which of the env's keys ``name`` is (a sentence for an error), or None if none."""
    if name in OBSERVATION_KEYS:
        return f"the env writes obs[{name!r}]"
    if name in INFO_KEYS:
        return f"the env writes info[{name!r}]"
    if name in FLAT_KEYS:
        return f"{name!r} is the flat observation's whole slice"
    return None


def estimator_name_reason(name: str) -> str | None:
    """Why ``name`` may not name an estimator (it is one of the env's keys, or one of the info keys
    it would write is), or None if it may."""
    reason = env_key_reason(name)
    if reason is not None:
        return reason
    key = _prefixes(OBSERVATION_KEYS | INFO_KEYS).get(name)
    if key is not None:
        return f"the estimator would write info[{key!r}], which the env writes"
    return None


def reserved_estimator_names() -> frozenset[str]:
    """Every name :func:`estimator_name_reason` refuses."""
    keys = OBSERVATION_KEYS | INFO_KEYS
    return frozenset(keys | FLAT_KEYS | set(_prefixes(keys)))
