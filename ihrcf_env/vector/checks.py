"""The vector envs' argument checks: what ``gym.make_vec`` and each ``reset``/``step`` are given is
checked whole here, before any env is built, reset or stepped, and refused with an error naming
the argument (and the env rows at fault).

Pure numpy and Gymnasium's registry; no simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from numpy.typing import NDArray

from ihrcf_env.core.checks import check_int

__all__ = [
    "MAX_ENVS",
    "MAX_SEED",
    "UNSUPPORTED_OPTIONS",
    "check_actions",
    "check_autoreset_mode",
    "check_env_mask",
    "check_options",
    "env_seeds",
    "rows_text",
    "split_reset_mask",
    "time_limit",
]

#: Largest ``num_envs`` of one process (each env holds a physics client).
MAX_ENVS = 1024
#: Options the vector env does not take (a GUI is one per process; the vector env does not render).
UNSUPPORTED_OPTIONS = ("render_mode",)
#: Most rows an error message lists one by one.
_ROWS_SHOWN = 8


def rows_text(rows: Sequence[int] | NDArray[np.intp]) -> str:
    """``"row 3"``, ``"rows [1, 4]"`` (the first few of many, then their count)."""
    rows = [int(r) for r in rows]
    if len(rows) == 1:
        return f"row {rows[0]}"
    shown = ", ".join(str(r) for r in rows[:_ROWS_SHOWN])
    more = f", ... ({len(rows)} rows)" if len(rows) > _ROWS_SHOWN else ""
    return f"rows [{shown}{more}]"


def check_actions(actions: Any, n: int, shape: tuple[int, ...]) -> NDArray[Any]:
    """``actions`` as an array of shape ``(n, *shape)`` of finite real numbers; TypeError (not
    numbers) / ValueError (the wrong shape, NaN or inf: naming the rows) naming ``actions``
    otherwise. Checked whole, so that no env steps when one row is bad."""
    a = np.asarray(actions)
    want = (n, *shape)
    if a.dtype.kind not in "fiu":
        raise TypeError(f"actions: real numbers, got dtype {a.dtype}")
    if a.shape != want:
        raise ValueError(f"actions: shape {want} (num_envs, action), got {a.shape}")
    if a.dtype.kind == "f":
        bad = np.flatnonzero(~np.isfinite(a.reshape(n, -1)).all(axis=1))
        if bad.size:
            raise ValueError(
                f"actions: {rows_text(bad)} (one row per env) hold NaN or inf, e.g. "
                f"{a[bad[0]].tolist()}; no env was stepped"
            )
    return a


def check_env_mask(name: str, mask: Any, n: int) -> NDArray[np.bool_]:
    """A copy of ``mask``, checked to be a numpy bool array of shape ``(n,)`` marking at least one
    env (ValueError / TypeError naming ``name`` otherwise)."""
    if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
        raise TypeError(f"{name}: a numpy array of dtype bool, got {type(mask).__name__}")
    if mask.shape != (n,):
        raise ValueError(f"{name}: shape ({n},) (one flag per env), got {mask.shape}")
    if not mask.any():
        raise ValueError(f"{name}: marks no env (at least one True)")
    return mask.copy()


#: The largest seed of an env of a vector env (every backend's episode keys are below 2**63).
MAX_SEED = 2**63 - 1


def env_seeds(seed: int | Sequence[int | None] | None, n: int) -> list[int | None]:
    """The seed of each of ``n`` envs from a vector env's ``reset(seed=...)``: an int ``s`` gives
    ``s + i`` to env ``i``; a sequence gives one seed (or None) per env; None leaves all unseeded.
    Every env's seed is in [0, :data:`MAX_SEED`], however it is given."""
    if seed is None:
        return [None] * n
    if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
        s = check_int("seed", seed, low=0, high=MAX_SEED + 1 - n)
        return [s + i for i in range(n)]
    if isinstance(seed, Sequence) and not isinstance(seed, str):
        if len(seed) != n:
            raise ValueError(f"seed: a sequence of {n} seeds (one per env), got {len(seed)}")
        return [
            None if s is None else check_int(f"seed[{i}]", s, low=0, high=MAX_SEED)
            for i, s in enumerate(seed)
        ]
    raise TypeError(f"seed must be an int >= 0, a sequence of {n} of them or None, got {seed!r}")


def split_reset_mask(
    options: dict[str, Any] | None, n: int
) -> tuple[NDArray[np.bool_] | None, dict[str, Any] | None]:
    """``options["reset_mask"]`` checked (:func:`check_env_mask`) and the other options (None when
    none are left)."""
    if not options or "reset_mask" not in options:
        return None, options
    rest = {k: v for k, v in options.items() if k != "reset_mask"}
    return check_env_mask("options['reset_mask']", options["reset_mask"], n), rest or None


def check_autoreset_mode(autoreset_mode: object) -> AutoresetMode:
    """``autoreset_mode`` (an :class:`AutoresetMode` or its value) as the enum: NEXT_STEP or
    SAME_STEP; ValueError naming it otherwise."""
    modes = {m.value: m for m in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)}
    mode = autoreset_mode.value if isinstance(autoreset_mode, AutoresetMode) else autoreset_mode
    if not isinstance(mode, str) or mode not in modes:
        raise ValueError(
            f"autoreset_mode must be one of {sorted(modes)} (AutoresetMode.NEXT_STEP or SAME_STEP), "
            f"got {autoreset_mode!r}"
        )
    return modes[mode]


def time_limit(env_id: str, max_episode_steps: object) -> int | None:
    """The episodes' step limit as ``gym.make(env_id, max_episode_steps=...)`` sets it: None takes
    the id's registered ``max_episode_steps``, -1 none, a positive int that many steps. Returns the
    limit (None: none)."""
    if max_episode_steps is None:
        registered = gym.spec(env_id).max_episode_steps
        return None if registered is None else check_int("max_episode_steps", registered, low=1)
    steps = check_int("max_episode_steps", max_episode_steps)
    if steps == -1:
        return None
    if steps < 1:
        raise ValueError(
            f"max_episode_steps must be a positive integer (steps), -1 (no limit) or None (the "
            f"id's registered limit), got {steps}"
        )
    return steps


def check_options(options: dict[str, Any]) -> None:
    """Refuse the options the vector env does not take (:data:`UNSUPPORTED_OPTIONS`) by name."""
    bad = sorted(set(options) & set(UNSUPPORTED_OPTIONS))
    if bad:
        raise ValueError(f"{bad[0]}: not supported by the vector env (make single envs to render)")
