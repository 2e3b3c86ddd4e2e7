"""``ihrcf_env.fast.observe`` against ``LandingObservation`` (float64): PyBullet landing envs
(projected camera, corners) flown by the scripted landing are recorded step by step (raw
observation, info, the wrapper's observation); the JAX stage and observation run over the recorded
raw readings and must give the wrapper's observation and each estimate's validity and reason.

The observation is float32; the estimators' arithmetic differs at rounding level (and the LM from
cv2's by up to a few 1e-5 in rare poses), so vectors are compared within ``OBS_TOL`` and the
reason texts must agree on all but ``MAX_REASON_MISMATCH`` of the step-estimator pairs. The JAX
step compiles for minutes on CPU: the golden tests are ``slow`` and share one compiled function
per configuration.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from ihrcf_env.config.make import make_config
from ihrcf_env.control.policies import ScriptedLanding
from ihrcf_env.wrappers.landing_obs import LandingObservation, landing_obs_fields, make_landing

jax = pytest.importorskip("jax")

from ihrcf_env.fast import observe as ob  # noqa: E402
from ihrcf_env.fast.raw import RawReading, Truth  # noqa: E402

#: Largest difference allowed between the observation vectors (scaled units).
OBS_TOL = 1e-4
#: Share of step-estimator pairs whose reason text may differ (an LM difference flipping a gate).
MAX_REASON_MISMATCH = 0.02
#: Largest differences allowed in the forecast: the block (scaled units) and the mean and std of
#: ``info["forecast"]`` (m, m/s, rad). The fit on a sliding window amplifies the fused estimate's
#: rounding-level differences.
FORECAST_OBS_TOL = 1e-3
FORECAST_TOL = 1e-4
STEPS = 300


def _config(task: str, **options: Any) -> Any:
    return make_config(task=task, camera_model="projected", camera_output="corners", **options)


def _record(cfg: Any, seed: int, steps: int = STEPS) -> tuple[list, list, list]:
    """(raw records (obs, info), the wrapper's observations, its infos) of one scripted episode."""
    env = make_landing(cfg.task_name, config=cfg)
    assert isinstance(env, LandingObservation)
    raw_env = env.env
    recs: list[tuple[dict, dict]] = []
    step, reset = raw_env.step, raw_env.reset

    def rstep(a: Any) -> Any:
        r = step(a)
        recs.append((r[0], dict(r[4])))
        return r

    def rreset(**kw: Any) -> Any:
        r = reset(**kw)
        recs.append((r[0], dict(r[1])))
        return r

    raw_env.step, raw_env.reset = rstep, rreset  # type: ignore[method-assign]
    try:
        pol = ScriptedLanding.from_env(env)
        obs, info = env.reset(seed=seed)
        pol.reset()
        outs, infos = [obs], [dict(info)]
        for _ in range(steps):
            obs, _, term, trunc, info = env.step(pol.act(obs))
            outs.append(obs)
            infos.append(dict(info))
            if term or trunc:
                break
    finally:
        env.close()
    return recs, outs, infos


def _reading(rec: tuple[dict, dict]) -> tuple[RawReading, Truth]:
    o, info = rec
    imu = o["imu"]

    def f(x: Any) -> np.ndarray:
        return np.asarray(x, np.float64)

    raw = RawReading(
        np.float64(0.0),
        f(o["tag_corners"]),
        np.bool_(o["tag_detected"]),
        np.int32(o["tag_status"]),
        f(o["camera_age"]).reshape(()),
        np.int32(np.asarray(o.get("camera_frame", [0])).ravel()[0]),
        f(o["ranges"]),
        np.asarray(o["ranges_valid"]).astype(bool),
        f(imu["quaternion"]),
        f(imu["angular_velocity"]),
        f(imu["linear_acceleration"]),
        f(o["nav_velocity"]),
    )
    return raw, Truth(*(f(info[k]) for k in Truth._fields))


class Compiled:
    """One configuration's params and its jitted :func:`observe`, counting its traces."""

    def __init__(self, cfg: Any) -> None:
        self.params = ob.observe_params(cfg)
        self.traces = 0
        self.apart_worst = 0.0

        def step(st: Any, raw: RawReading, truth: Truth) -> Any:
            self.traces += 1
            return ob.observe(self.params, st, raw, truth)

        self.fn: Callable[..., Any] = jax.jit(step)


def _compare(
    c: Compiled, recs: list, outs: list, infos: list, apart: slice | None = None
) -> tuple[float, int, int]:
    """Run the JAX observation over an episode: (max |difference| outside ``apart``, reason
    mismatches, pairs); the largest difference inside ``apart`` is left in ``c.apart_worst``."""
    p = c.params
    st = ob.observe_reset(p, ob.observe_init(p))
    worst, mismatch, pairs = 0.0, 0, 0
    inside = np.zeros(outs[0].shape, bool)
    if apart is not None:
        inside[apart] = True
    c.apart_worst = 0.0
    for k, rec in enumerate(recs):
        out, st, est = c.fn(st, *_reading(rec))
        out = np.asarray(out)
        assert out.dtype == np.float32 and out.shape == outs[k].shape
        assert np.all(np.isfinite(out))
        diff = np.abs(out.astype(np.float64) - outs[k])
        worst = max(worst, float(np.max(diff[~inside])))
        c.apart_worst = max(c.apart_worst, float(np.max(diff, where=inside, initial=0.0)))
        for name in p.names:
            e = jax.tree_util.tree_map(np.asarray, est[name])
            pairs += 1
            ref = infos[k][f"{name}_reason"]
            mismatch += ob.reason_text(p, name, e) != ref
            assert bool(e.valid) == (ref == "") or ob.reason_text(p, name, e) != ref
            age = infos[k][f"{name}_age"]
            assert (np.isnan(age) and np.isnan(e.age)) or abs(float(e.age) - age) < 1e-9
    return worst, mismatch, pairs


def _same_params(a: ob.ObserveParams, b: ob.ObserveParams) -> bool:
    """The static values two configurations' params are built from agree (arrays by value)."""
    for fld in dataclasses.fields(a):
        x, y = getattr(a, fld.name), getattr(b, fld.name)
        lx, ly = jax.tree_util.tree_leaves(x), jax.tree_util.tree_leaves(y)
        if len(lx) != len(ly):
            return False
        for u, v in zip(lx, ly, strict=True):
            if isinstance(u, np.ndarray | jax.Array) or isinstance(v, np.ndarray | jax.Array):
                if np.shape(u) != np.shape(v) or not np.array_equal(
                    np.asarray(u), np.asarray(v), equal_nan=True
                ):
                    return False
            elif u != v:
                return False
    return True


# -- fast checks (no compilation) ----------------------------------------------------------------
@pytest.mark.parametrize(
    "task, options",
    [
        ("landing-v1", {}),
        ("landing-v2", {}),
        ("landing-v2", {"deck_motion": True, "privileged": True}),
        ("landing-v2", {"estimators": ("fused", "ihrcf")}),
    ],
)
def test_layout_is_the_wrappers(task: str, options: dict) -> None:
    cfg = _config(task, **options)
    p = ob.observe_params(cfg)
    o = cfg.observation
    slices, scales, low, high = landing_obs_fields(
        o.estimators, cfg.world.tof.max_range, o.privileged, o.deck_motion
    )
    assert p.slices == slices and p.scales == scales and p.size == slices["all"].stop
    np.testing.assert_array_equal(p.low, low)
    np.testing.assert_array_equal(p.high, high)
    assert p.names == tuple(o.estimators)
    assert p.counted == (task == "landing-v2")


def test_the_forecast_block_is_the_wrappers() -> None:
    cfg = _config("landing-v2", deck_forecast={"horizons": (0.5, 1.0, 2.0)})
    p = ob.observe_params(cfg)
    o = cfg.observation
    slices, scales, low, high = landing_obs_fields(o.estimators, cfg.world.tof.max_range, False, False, 3)
    assert p.slices == slices and p.scales == scales
    np.testing.assert_array_equal(p.low, low)
    np.testing.assert_array_equal(p.high, high)
    assert p.forecast is not None and p.forecast.size == 8 * 3 + 2
    assert not _same_params(p, ob.observe_params(_config("landing-v2")))


def test_refused_options_are_named() -> None:
    with pytest.raises(ValueError, match="raw"):
        ob.observe_params(_config("landing-v2", raw=True))
    with pytest.raises(ValueError, match="camera_output"):
        ob.observe_params(make_config(task="landing-v2", camera_model="projected", camera_output="image"))
    with pytest.raises(TypeError, match="config"):
        ob.observe_params({"task": "landing-v2"})  # type: ignore[arg-type]


def test_the_stages_constants_are_the_simulators() -> None:
    from ihrcf_env.sim.sensors import timing
    from ihrcf_env.sim.sensors.base import TAG_STATUS

    assert ob.NO_FRAME_YET == timing.NO_FRAME_YET
    assert ob.TICK_EPS == timing._TICK_EPS
    assert tuple(ob.STATUS_NAMES) == tuple(TAG_STATUS)


def test_levels_share_one_configuration() -> None:
    """The v2 levels' observation params agree (one compiled function serves them all)."""
    base = ob.observe_params(_config("landing-v2", level="moderate"))
    for level in ("calm", "rough"):
        assert _same_params(base, ob.observe_params(_config("landing-v2", level=level)))
    assert not _same_params(base, ob.observe_params(_config("landing-v2", deck_motion=True)))


# -- golden tests against the PyBullet env (slow: minutes of compilation) -------------------------
@pytest.fixture(scope="module")
def v2() -> Compiled:
    return Compiled(_config("landing-v2", level="moderate"))


@pytest.mark.slow
@pytest.mark.parametrize("level, seed", [("calm", 11), ("moderate", 1), ("moderate", 12), ("rough", 13)])
def test_v2_matches_landing_observation(v2: Compiled, level: str, seed: int) -> None:
    cfg = _config("landing-v2", level=level)
    assert _same_params(v2.params, ob.observe_params(cfg))
    worst, mismatch, pairs = _compare(v2, *_record(cfg, seed))
    assert worst <= OBS_TOL
    assert mismatch <= MAX_REASON_MISMATCH * pairs
    assert v2.traces == 1  # compiled once for every episode and level


@pytest.mark.slow
def test_v1_default_layout_matches() -> None:
    cfg = _config("landing-v1")
    c = Compiled(cfg)
    worst, mismatch, pairs = _compare(c, *_record(cfg, 3, 200))
    assert worst <= OBS_TOL
    assert mismatch <= MAX_REASON_MISMATCH * pairs
    assert c.traces == 1


@pytest.mark.slow
def test_deck_motion_and_privileged_blocks_match() -> None:
    cfg = _config("landing-v2", level="rough", deck_motion=True, privileged=True)
    c = Compiled(cfg)
    recs, outs, infos = _record(cfg, 5)
    worst, mismatch, pairs = _compare(c, recs, outs, infos)
    assert worst <= OBS_TOL
    assert mismatch <= MAX_REASON_MISMATCH * pairs
    sl = c.params.slices
    shown = np.array([o[sl["motion"]] for o in outs])
    assert np.any(shown != 0.0)  # the filter converged and its motion is shown
    assert np.all(np.array([o[sl["ground_truth"]] for o in outs])[:, 2] != 0.0)


@pytest.mark.slow
def test_deck_forecast_block_matches() -> None:
    """The forecast block (fed by the fused estimate, fitted within the episode) and the rest of
    the observation against the wrapper's; ``info["forecast"]`` against the JAX state's output."""
    quick = {"window": 8.0, "min_span": 4.0, "order": 8, "horizons": (0.5, 1.0)}
    cfg = _config("landing-v2", level="rough", deck_forecast=quick)
    c = Compiled(cfg)
    recs, outs, infos = _record(cfg, 13)
    sl = c.params.slices
    worst, mismatch, pairs = _compare(c, recs, outs, infos, apart=sl["forecast"])
    assert worst <= OBS_TOL
    assert c.apart_worst <= FORECAST_OBS_TOL
    assert mismatch <= MAX_REASON_MISMATCH * pairs
    fitted = np.array([o[sl["forecast.valid"]][0] for o in outs])
    assert fitted.sum() >= 20  # the forecaster fitted and its forecast was compared
    p = c.params
    st = ob.observe_reset(p, ob.observe_init(p))
    for k, rec in enumerate(recs):
        _, st, _ = c.fn(st, *_reading(rec))
        ref = infos[k]["forecast"]
        fc = jax.tree_util.tree_map(np.asarray, st.forecast)
        assert bool(fc.valid) == ref["valid"]
        np.testing.assert_allclose(fc.mean, ref["mean"], atol=FORECAST_TOL)
        np.testing.assert_allclose(fc.std, ref["std"], atol=FORECAST_TOL / 10)
        assert abs(float(fc.quiet) - ref["quiet_probability"]) <= 1e-4
        assert int(np.asarray(st.feed.samples)) == ref["samples"]
