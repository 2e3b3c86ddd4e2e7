"""The deck-landing tasks' rules as pure functions of arrays: outcome and touchdown classification,
success, termination and reward terms (no simulator, no Gymnasium).

The state is a :class:`~ihrcf_env.tasks.state.TaskState` (and a
:class:`~ihrcf_env.tasks.state.TouchdownState` for the step's contact), NamedTuples of arrays;
every rule runs on numpy or ``jax.numpy`` arrays (the namespace of its inputs, through
``array-api-compat``), on one drone (0-d results) or a batch over leading axes, and contains no
Python branching on array values, so the PyBullet env and a compiled backend run the same code.
The task's parameters are its :class:`~ihrcf_env.envs.task_config.TaskConfig` parts (any objects
with their fields).
"""

from ihrcf_env.tasks.outcome import (
    CRASH_ARENA,
    CRASH_BASE,
    CRASH_GROUND,
    CRASH_OFF_DECK,
    CRASH_OFF_TAG,
    CRASH_SPEED,
    CRASH_TILT,
    CRASH_TOUCHDOWN_TILT,
    FLYING,
    OUTCOME_NAMES,
    SUCCESS,
    classify,
    describe,
    is_crash,
    is_success,
    is_terminal,
    outcome_name,
    relative_tilt,
    tag_offset,
    tilt,
    touchdown_state,
)
from ihrcf_env.tasks.reward import (
    LEG_LENGTH,
    HoverRewardTerms,
    LandingRewardTerms,
    action_cost,
    failure_penalty,
    hover_reward,
    landing_potential,
    landing_reward,
    miss,
    total,
)
from ihrcf_env.tasks.state import (
    CONTACT_BASE,
    CONTACT_DECK,
    CONTACT_GROUND,
    CONTACT_NAMES,
    NO_CONTACT,
    TaskState,
    TouchdownState,
)

__all__ = [
    "CONTACT_BASE",
    "CONTACT_DECK",
    "CONTACT_GROUND",
    "CONTACT_NAMES",
    "CRASH_ARENA",
    "CRASH_BASE",
    "CRASH_GROUND",
    "CRASH_OFF_DECK",
    "CRASH_OFF_TAG",
    "CRASH_SPEED",
    "CRASH_TILT",
    "CRASH_TOUCHDOWN_TILT",
    "FLYING",
    "LEG_LENGTH",
    "NO_CONTACT",
    "OUTCOME_NAMES",
    "SUCCESS",
    "HoverRewardTerms",
    "LandingRewardTerms",
    "TaskState",
    "TouchdownState",
    "action_cost",
    "classify",
    "describe",
    "failure_penalty",
    "hover_reward",
    "is_crash",
    "is_success",
    "is_terminal",
    "landing_potential",
    "landing_reward",
    "miss",
    "outcome_name",
    "relative_tilt",
    "tag_offset",
    "tilt",
    "total",
    "touchdown_state",
]
