"""The task rules (``ihrcf_env.tasks``) as pure functions: against a plain scalar statement of
each rule (Python floats and ``math``, as the env computed them before), to rounding (1e-12); one drone
(0-d) against a batch row by row; the classification's cases; jitted JAX against numpy."""

from __future__ import annotations

import decimal
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ihrcf_env import tasks
from ihrcf_env.config.task import Arena, RewardWeights, RewardWeightsV1, Thresholds
from ihrcf_env.tasks._math import hypot

N = 256
TH, ARENA = Thresholds(), Arena()
W, WV1 = RewardWeights(), RewardWeightsV1()
RADIUS, DT, HALF = 0.15, 0.05, 0.3


def _batch(seed: int = 0, n: int = N) -> tuple[tasks.TaskState, tasks.TouchdownState, Any, Any]:
    """Random states near the deck (some tilted, some outside the arena), touchdowns of every kind
    (speed and tilt around the limits), actions in [-1, 1]^4 and outcome codes."""
    rng = np.random.default_rng(seed)
    tilt = rng.uniform(0.0, 1.4, n)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    drone_R = Rotation.from_rotvec(axis * tilt[:, None]).as_matrix()
    deck_R = Rotation.from_euler("xyz", rng.uniform(-0.2, 0.2, (n, 3))).as_matrix()
    deck_p = rng.uniform(-0.5, 0.5, (n, 3)) * [1, 1, 0.2] + [0, 0, 1.0]
    drone_p = deck_p + rng.normal(size=(n, 3)) * [0.3, 0.3, 0.5]
    drone_p[: n // 8, 0] = rng.choice([-6.0, 6.0], n // 8)  # outside the arena
    drone_p[n // 8 : n // 4, 2] = 7.0  # over the ceiling
    drone_p[-n // 4 :, :2] = deck_p[-n // 4 :, :2] + rng.normal(size=(n // 4, 2)) * 0.05  # near the tag
    state = tasks.TaskState(
        drone_position=drone_p,
        drone_rotation=drone_R,
        drone_velocity=rng.normal(size=(n, 3)),
        deck_position=deck_p,
        deck_rotation=deck_R,
        deck_point_velocity=rng.normal(size=(n, 3)) * 0.3,
    )
    td = tasks.TouchdownState(
        contact=rng.integers(0, 4, n),
        relative_vertical_speed=rng.uniform(-1.0, 0.2, n),
        relative_tilt=rng.uniform(0.0, 0.4, n),
        on_deck=rng.uniform(size=n) < 0.8,
    )
    return state, td, rng.uniform(-1, 1, (n, 4)), rng.integers(0, len(tasks.OUTCOME_NAMES), n)


def _row(tree: Any, i: int) -> Any:
    return type(tree)(*(np.asarray(f)[i] for f in tree))


# -- the rules as the env stated them with Python floats (the reference) -----------------------
def _ref_relative_tilt(s: tasks.TaskState) -> float:
    c = float(s.drone_rotation[:, 2] @ s.deck_rotation[:, 2])
    return math.acos(max(-1.0, min(1.0, c)))


def _ref_offset(s: tasks.TaskState) -> float:
    return math.hypot(*(s.drone_position[:2] - s.deck_position[:2]))


def _ref_code(s: tasks.TaskState, td: tasks.TouchdownState, radius: float | None) -> int:
    if int(td.contact) != tasks.NO_CONTACT:
        body = tasks.CONTACT_NAMES[int(td.contact)]
        if body != "deck":
            return tasks.CRASH_GROUND if body == "ground" else tasks.CRASH_BASE
        if not td.on_deck:
            return tasks.CRASH_OFF_DECK
        if abs(float(td.relative_vertical_speed)) >= TH.success_speed:
            return tasks.CRASH_SPEED
        if float(td.relative_tilt) >= TH.success_tilt:
            return tasks.CRASH_TOUCHDOWN_TILT
        if radius is not None and _ref_offset(s) > radius:
            return tasks.CRASH_OFF_TAG
        return tasks.SUCCESS
    pos, R = s.drone_position, s.drone_rotation
    if math.acos(max(-1.0, min(1.0, R[2, 2]))) > TH.crash_tilt:
        return tasks.CRASH_TILT
    if abs(pos[0]) > ARENA.half_width or abs(pos[1]) > ARENA.half_width or pos[2] > ARENA.ceiling:
        return tasks.CRASH_ARENA
    return tasks.FLYING


def _ref_hover(s: tasks.TaskState, a: Any, code: int) -> list[float]:
    e = s.drone_position - s.deck_position
    outcome = tasks.outcome_name(code)
    return [
        -W.position_xy * math.hypot(e[0], e[1]) - W.position_z * max(float(e[2]), 0.0),
        -W.velocity * float(np.linalg.norm(s.drone_velocity - s.deck_point_velocity)),
        -W.attitude * _ref_relative_tilt(s),
        -W.action * float(a @ a),
        W.success if outcome == "success" else (-W.crash if outcome == "crash" else 0.0),
    ]


def _ref_potential(s: tasks.TaskState, td: tasks.TouchdownState | None) -> float:
    height = max(float(s.drone_position[2] - s.deck_position[2]) - tasks.LEG_LENGTH, 0.0)
    if td is not None and int(td.contact) != 0:
        speed = abs(float(td.relative_vertical_speed))
    else:
        speed = float(np.linalg.norm(s.drone_velocity - s.deck_point_velocity))
    return -(WV1.distance * _ref_offset(s) + WV1.height * height + WV1.speed * speed)


def _ref_miss(s: tasks.TaskState, td: tasks.TouchdownState) -> float:
    if int(td.contact) != tasks.CONTACT_DECK or not td.on_deck:
        return math.inf
    return max(
        abs(float(td.relative_vertical_speed)) / TH.success_speed,
        float(td.relative_tilt) / TH.success_tilt,
        _ref_offset(s) / RADIUS,
    )


def _ref_landing(s: tasks.TaskState, a: Any, code: int, td: tasks.TouchdownState, prev: float) -> list[float]:
    outcome = tasks.outcome_name(code)
    phi = _ref_potential(s, td if outcome != "flying" else None)
    penalty = WV1.near_miss + (WV1.crash - WV1.near_miss) * min(1.0, max(0.0, _ref_miss(s, td) - 1.0))
    return [
        phi - prev,
        -WV1.time * DT,
        -WV1.action * float(a @ a) * DT,
        WV1.success if outcome == "success" else (-penalty if outcome == "crash" else 0.0),
    ]


def _close(a: Any, b: Any) -> bool:
    """Equal to rounding: numpy's vector loops and Python's scalar libm may differ in the last bit
    (the platform's SIMD transcendental functions), so the rules are checked to 1e-12."""
    return bool(np.allclose(np.asarray(a, np.float64), np.asarray(b, np.float64), rtol=1e-12, atol=1e-12))


# -- tests ---------------------------------------------------------------------------------------
def _exact_hypot(a: float, b: float) -> float:
    """``sqrt(a**2 + b**2)`` of two finite floats from 60-digit decimal arithmetic, rounded once to
    the nearest float (subnormals included)."""
    with decimal.localcontext() as ctx:
        ctx.prec = 60
        return float((decimal.Decimal(a) ** 2 + decimal.Decimal(b) ** 2).sqrt())


def test_hypot_is_correctly_rounded_to_the_last_bit() -> None:
    """The array ``hypot`` against the exact value to rounding (at most one unit in the last
    place, subnormals included), as Python's ``math.hypot`` is: not to one interpreter's bits
    (CPython 3.12 changed ``math.hypot``'s last bit for subnormal inputs)."""
    rng = np.random.default_rng(3)
    for scale in (1.0, 1e-3, 1e4, 1e-200, 1e-310, 1e300):
        x, y = rng.normal(size=2000) * scale, rng.normal(size=2000) * scale
        exact = np.array([_exact_hypot(a, b) for a, b in zip(x, y, strict=True)])
        ulp = np.spacing(exact)
        got = hypot(np, x, y)
        assert np.all(np.abs(got - exact) <= ulp), (scale, np.max(np.abs(got - exact) / ulp))
        scalar = np.array([math.hypot(a, b) for a, b in zip(x, y, strict=True)])
        assert np.all(np.abs(got - scalar) <= 2 * ulp), scale  # each within one ulp of the exact value
    special = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, 3.0])
    x, y = np.meshgrid(special, special)
    ref = np.array([math.hypot(a, b) for a, b in zip(x.ravel(), y.ravel(), strict=True)])
    got = hypot(np, x.ravel(), y.ravel())
    np.testing.assert_allclose(got, ref, rtol=0.0, atol=5e-324)  # inf and NaN where Python's are
    assert float(hypot(np, np.float64(3.0), np.asarray(4.0))) == 5.0


def test_rules_equal_the_scalar_statement() -> None:
    state, td, action, codes = _batch()
    offsets = tasks.tag_offset(state)
    tilts = tasks.relative_tilt(state.drone_rotation, state.deck_rotation)
    hover_codes = tasks.classify(state, td, TH, ARENA)
    landing_codes = tasks.classify(state, td, TH, ARENA, RADIUS)
    hover = tasks.hover_reward(state, action, codes, W)
    landing, phi = tasks.landing_reward(state, action, codes, td, np.full(N, 0.25), WV1, TH, RADIUS, DT)
    misses = tasks.miss(state, td, TH, RADIUS)
    for i in range(N):
        s, t, a, code = _row(state, i), _row(td, i), action[i], int(codes[i])
        assert _close(offsets[i], _ref_offset(s))
        assert _close(tilts[i], _ref_relative_tilt(s))
        assert int(hover_codes[i]) == _ref_code(s, t, None), i
        assert int(landing_codes[i]) == _ref_code(s, t, RADIUS), i
        assert _close([f[i] for f in hover], _ref_hover(s, a, code)), i
        assert _close([f[i] for f in landing], _ref_landing(s, a, code, t, 0.25)), i
        assert _close(float(tasks.total(tuple(f[i] for f in hover))), sum(_ref_hover(s, a, code)))
        assert _close(misses[i], _ref_miss(s, t))
    # every outcome occurs in the batch
    assert set(np.unique(landing_codes)) >= set(range(2, len(tasks.OUTCOME_NAMES))) | {0, 1}


def test_touchdown_state_is_the_worlds_old_record() -> None:
    state, _, _, _ = _batch(1)
    approach = np.random.default_rng(2).normal(size=(N, 3))
    td = tasks.touchdown_state(state, np.full(N, tasks.CONTACT_DECK), approach, HALF)
    for i in range(N):
        s = _row(state, i)
        local = s.deck_rotation.T @ (s.drone_position - s.deck_position)
        v_rel = approach[i] - s.deck_point_velocity
        assert _close(td.relative_vertical_speed[i], float(v_rel @ s.deck_rotation[:, 2]))
        assert _close(td.relative_tilt[i], _ref_relative_tilt(s))
        assert bool(td.on_deck[i]) == bool(abs(local[0]) <= HALF and abs(local[1]) <= HALF)
    assert 0 < int(np.sum(td.on_deck)) < N


RULES: dict[str, Callable[[tasks.TaskState, tasks.TouchdownState, Any, Any], Any]] = {
    "tag_offset": lambda s, td, a, c: tasks.tag_offset(s),
    "relative_tilt": lambda s, td, a, c: tasks.relative_tilt(s.drone_rotation, s.deck_rotation),
    "tilt": lambda s, td, a, c: tasks.tilt(s.drone_rotation),
    "touchdown_state": lambda s, td, a, c: tasks.touchdown_state(s, td.contact, s.drone_velocity * 0.5, HALF),
    "classify_hover": lambda s, td, a, c: tasks.classify(s, td, TH, ARENA),
    "classify_landing": lambda s, td, a, c: tasks.classify(s, td, TH, ARENA, RADIUS),
    "hover_reward": lambda s, td, a, c: tasks.hover_reward(s, a, c, W),
    "landing_potential": lambda s, td, a, c: tasks.landing_potential(s, WV1, td),
    "miss": lambda s, td, a, c: tasks.miss(s, td, TH, RADIUS),
    "failure_penalty": lambda s, td, a, c: tasks.failure_penalty(tasks.miss(s, td, TH, RADIUS), WV1),
    "landing_reward": lambda s, td, a, c: tasks.landing_reward(
        s, a, c, td, s.drone_position[..., 0], WV1, TH, RADIUS, DT
    ),
    "terminal": lambda s, td, a, c: (tasks.is_terminal(c), tasks.is_success(c), tasks.is_crash(c)),
}


def _leaves(x: Any) -> list[Any]:
    if isinstance(x, tuple):
        return [leaf for item in x for leaf in _leaves(item)]
    return [x]


@pytest.mark.parametrize("name", sorted(RULES))
def test_one_drone_equals_its_row_of_a_batch(name: str) -> None:
    state, td, action, codes = _batch(4, 64)
    rule = RULES[name]
    batched = _leaves(rule(state, td, action, codes))
    for i in range(64):
        single = _leaves(rule(_row(state, i), _row(td, i), action[i], np.asarray(codes[i])))
        assert len(single) == len(batched)
        for b, one in zip(batched, single, strict=True):
            assert np.shape(one) == ()
            assert _close(np.asarray(b)[i], one), (name, i)


def test_outcome_cases() -> None:
    """One drone per outcome, built by hand: each check fires where it should and names itself."""
    level, up = np.eye(3), np.zeros(3)
    base = tasks.TaskState(np.array([0.0, 0.0, 1.1]), level, up, np.array([0.0, 0.0, 1.0]), level, up)
    none = tasks.TouchdownState(np.asarray(0), np.asarray(0.0), np.asarray(0.0), np.asarray(False))
    soft = tasks.TouchdownState(np.asarray(1), np.asarray(-0.2), np.asarray(0.05), np.asarray(True))

    def code(
        s: tasks.TaskState = base, td: tasks.TouchdownState = none, radius: float | None = RADIUS
    ) -> str:
        return tasks.OUTCOME_NAMES[int(tasks.classify(s, td, TH, ARENA, radius))]

    assert code() == "flying"
    assert code(td=soft) == "success"
    assert code(td=soft._replace(contact=np.asarray(2))) == "hit_ground"
    assert code(td=soft._replace(contact=np.asarray(3))) == "hit_base"
    assert code(td=soft._replace(on_deck=np.asarray(False))) == "off_deck"
    assert code(td=soft._replace(relative_vertical_speed=np.asarray(-0.5))) == "touchdown_speed"
    assert code(td=soft._replace(relative_tilt=np.asarray(TH.success_tilt))) == "touchdown_tilt"
    off = base._replace(drone_position=np.array([0.2, 0.0, 1.1]))
    assert code(off, soft) == "off_tag" and code(off, soft, None) == "success"
    flipped = Rotation.from_euler("x", TH.crash_tilt + 1e-9).as_matrix()
    assert code(base._replace(drone_rotation=flipped)) == "tilt"
    assert code(base._replace(drone_position=np.array([0.0, -5.01, 1.0]))) == "arena"
    assert code(base._replace(drone_position=np.array([0.0, 0.0, 6.01]))) == "arena"
    assert tasks.outcome_name(tasks.CRASH_ARENA) == "crash" and tasks.outcome_name(tasks.SUCCESS) == "success"
    reason = tasks.describe(tasks.CRASH_OFF_TAG, soft, off, TH, RADIUS)
    assert reason == "touched down 0.20 m from the tag centre (> 0.15 m)"
    assert (
        tasks.describe(tasks.SUCCESS, soft, base, TH) == ""
        and tasks.describe(tasks.FLYING, none, base, TH) == ""
    )
    fast = soft._replace(relative_vertical_speed=np.asarray(-1.234))
    assert tasks.describe(tasks.CRASH_SPEED, fast, base, TH) == "vertical speed 1.23 m/s at touchdown"


def test_failure_penalty_grades_the_near_miss() -> None:
    m = np.array([1.0, 1.5, 2.0, 3.0, np.inf])
    assert tasks.failure_penalty(m, WV1).tolist() == [20.0, 60.0, 100.0, 100.0, 100.0]


def test_a_non_array_input_is_refused() -> None:
    with pytest.raises(TypeError, match="array"):
        tasks.tilt(1.0)


@pytest.mark.parametrize("name", sorted(RULES))
def test_jax_jit_equals_numpy(name: str) -> None:
    jax = pytest.importorskip("jax")
    jax.config.update("jax_enable_x64", True)
    jnp = jax.numpy
    state, td, action, codes = _batch(5, 64)
    rule = RULES[name]
    want = _leaves(rule(state, td, action, codes))

    def to_jax(tree: Any) -> Any:
        return type(tree)(*(jnp.asarray(f) for f in tree))

    got = _leaves(jax.jit(rule)(to_jax(state), to_jax(td), jnp.asarray(action), jnp.asarray(codes)))
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert isinstance(g, jax.Array)
        g, w = np.asarray(g), np.asarray(w)
        assert g.shape == w.shape
        if w.dtype == bool or np.issubdtype(w.dtype, np.integer):
            assert np.array_equal(g, w), name
        else:
            assert np.allclose(g, w, rtol=0.0, atol=1e-12, equal_nan=True), name
