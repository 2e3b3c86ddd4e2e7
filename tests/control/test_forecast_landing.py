"""The forecast commit rule of the scripted landing that lands in the quiet: on synthetic forecasts,
its options, and a short closed loop."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from ihrcf_env.control.forecast_landing import (
    FORECAST_HORIZONS,
    ForecastCommitConfig,
    ForecastLandingController,
    _Forecast,
    check_window,
    forecast_commit_config,
    relative_tilt,
)
from ihrcf_env.control.landing import Measurement
from ihrcf_env.control.policies import V2_LANDING_CONFIG

H = np.asarray(FORECAST_HORIZONS)
LEAN = math.radians(15.0)
UP = np.array([math.sin(LEAN), 0.0, math.cos(LEAN)])  # the drone leans 15 deg about y (towards +x)


def _forecast(
    pitch: Callable[[np.ndarray], np.ndarray], std: float = math.radians(0.5)
) -> tuple[np.ndarray, ...]:
    """mean and std (H, 4) with the deck's pitch ``pitch(horizons)`` (rad), no roll, no heave rate."""
    mean = np.zeros((H.size, 4))
    mean[:, 3] = pitch(H)
    sd = np.full((H.size, 4), std)
    sd[:, 1] = 0.02
    return mean, sd


def test_relative_tilt_is_the_angle_between_the_deck_normal_and_the_drone_up() -> None:
    assert relative_tilt(0.0, 0.0, [0.0, 0.0, 1.0]) == pytest.approx(0.0, abs=1e-12)
    assert relative_tilt(0.0, LEAN, UP) == pytest.approx(0.0, abs=1e-9)  # deck pitched along the lean
    assert relative_tilt(0.0, -0.1, UP) == pytest.approx(LEAN + 0.1, abs=1e-9)
    # roll about x tilts the normal towards -y: perpendicular to the lean
    tilt = relative_tilt(0.1, 0.0, [0.0, 0.0, 1.0])
    assert tilt == pytest.approx(0.1, abs=1e-9)


def test_window_quiet_when_the_deck_tilts_along_the_lean() -> None:
    cfg = ForecastCommitConfig(max_tilt=math.radians(12.0))

    # deck pitch oscillating +-6 deg with a 4 s period; at 2 s it pitches +6 deg (along the lean)
    def pitch(t: np.ndarray) -> np.ndarray:
        return math.radians(6.0) * np.cos(2 * math.pi * (t - 2.0) / 4.0)

    mean, std = _forecast(pitch)
    good = check_window(H, mean, std, UP, 2.0, 0.2, cfg)
    assert good.ok and good.tilt < math.radians(12.0)
    bad = check_window(H, mean, std, UP, 4.0, 0.2, cfg)  # half a period later: pitched against it
    assert not bad.ok and bad.tilt > math.radians(19.0)


def test_window_margin_grows_with_the_forecast_sigma() -> None:
    cfg = ForecastCommitConfig(max_tilt=math.radians(16.5), k_sigma=2.0)
    mean, std = _forecast(lambda t: np.zeros_like(t))  # relative tilt 15 deg: the lean alone
    assert check_window(H, mean, std, UP, 2.0, 0.2, cfg).ok  # 15 + 2 x 0.5 deg < 16.5
    mean, std = _forecast(lambda t: np.zeros_like(t), std=math.radians(1.0))
    check = check_window(H, mean, std, UP, 2.0, 0.2, cfg)
    assert not check.ok and check.tilt == pytest.approx(math.radians(17.0), abs=1e-3)
    assert check_window(H, mean, std, UP, 2.0, 0.2, cfg, k=0.0).ok


def test_window_refuses_a_deck_rising_into_the_touchdown() -> None:
    cfg = ForecastCommitConfig(k_sigma=1.0)
    mean, std = _forecast(lambda t: np.full_like(t, LEAN))
    assert check_window(H, mean, std, UP, 2.0, 0.2, cfg).ok
    mean[:, 1] = 0.3  # heave rate up 0.3 m/s: 0.5 m/s relative
    check = check_window(H, mean, std, UP, 2.0, 0.2, cfg)
    assert not check.ok and check.speed == pytest.approx(0.52, abs=1e-9)


@pytest.mark.parametrize(
    ("key", "value", "error"),
    [
        ("max_tilt", -0.1, ValueError),
        ("max_speed", float("nan"), ValueError),
        ("k_sigma", "1", TypeError),
        ("points", 0, ValueError),
        ("points", 2.5, TypeError),
        ("arrival_spread", 6.0, ValueError),
        ("max_aborts", -1, ValueError),
    ],
)
def test_bad_options_are_refused_by_name(key: str, value: object, error: type[Exception]) -> None:
    with pytest.raises(error, match=f"ForecastCommitConfig.{key}"):
        ForecastCommitConfig(**{key: value})  # type: ignore[arg-type]


def test_unknown_option_is_named() -> None:
    with pytest.raises((TypeError, ValueError), match="forecast_commit.*bogus"):
        forecast_commit_config({"bogus": 1.0})


def test_controller_refuses_bad_horizons() -> None:
    with pytest.raises(ValueError, match="horizons"):
        ForecastLandingController((1.0, 0.5))


def _measure(ctrl: ForecastLandingController, height: float) -> Measurement:
    """A level drone (leaning 15 deg) centred over the tag, ``height`` above a level deck."""
    c, s = math.cos(LEAN), math.sin(LEAN)
    R_lb = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # body up along UP
    tag = ctrl.axis_point()
    return Measurement(
        rotation_level=R_lb,
        tag_xy=np.array(tag),
        tag_yaw=0.0,
        tag_normal=np.array([0.0, 0.0, 1.0]),
        tof_height=height,
        tof_normal=np.array([0.0, 0.0, 1.0]),
        tof_full=True,
        accel_z=0.0,
        tag_height=height,
        velocity_z=0.0,
        velocity_xy=np.zeros(2),
    )


def _run(
    forecast_at: Callable[[float], tuple[np.ndarray, np.ndarray]],
    steps: int,
    height: Callable[[ForecastLandingController], float] | None = None,
) -> tuple[ForecastLandingController, list[str]]:
    """Step the controller ``steps`` times at 20 Hz with the forecast ``forecast_at(t)``; the phases."""
    ctrl = ForecastLandingController(FORECAST_HORIZONS, config=V2_LANDING_CONFIG)
    ctrl.reset()
    phases = []
    for _ in range(steps):
        mean, std = forecast_at(ctrl.t)
        ctrl.forecast = _Forecast(mean, std, True)
        h = V2_LANDING_CONFIG.hold_height if height is None else height(ctrl)
        ctrl.act_measured(_measure(ctrl, h))
        phases.append(ctrl.phase)
    return ctrl, phases


def _along_the_lean_from(t0: float) -> Callable[[float], tuple[np.ndarray, np.ndarray]]:
    """A deck pitched 20 deg against the lean until ``t0`` s, then pitched along it."""

    def at(t: float) -> tuple[np.ndarray, np.ndarray]:
        return _forecast(lambda h: np.where(t + h < t0, -math.radians(10.0), LEAN))

    return at


def test_commits_in_a_quiet_window() -> None:
    ctrl, phases = _run(_along_the_lean_from(0.0), 40)
    assert "drop" in phases
    assert ctrl.commit_time is not None and ctrl.commit_time <= 1.5  # right after the settle time


def test_waits_through_a_rough_window() -> None:
    ctrl, phases = _run(_along_the_lean_from(8.0), 200)
    assert ctrl.commit_time is not None
    # commits only once the arrival falls in the quiet part (arrival ~ drop duration from now)
    arrival = ctrl.commit_time + ctrl.drop_duration()
    assert arrival >= 8.0 + ctrl.commit.arrival_spread - 0.1
    assert ctrl.commit_time < 8.0  # ... but before the quiet part starts: it sees it coming


def test_never_commits_into_a_forecast_that_stays_rough() -> None:
    ctrl, phases = _run(_along_the_lean_from(1e9), 200)
    assert "drop" not in phases and ctrl.commit_time is None


def test_aborts_when_the_forecast_turns() -> None:
    quiet = _along_the_lean_from(0.0)
    rough = _along_the_lean_from(1e9)
    state: dict[str, float] = {}

    def at(t: float) -> tuple[np.ndarray, np.ndarray]:
        # quiet until the commit, rough 0.3 s after it
        return rough(t) if "commit" in state and t > state["commit"] + 0.3 else quiet(t)

    ctrl = ForecastLandingController(FORECAST_HORIZONS, config=V2_LANDING_CONFIG)
    ctrl.reset()
    phases = []
    for _ in range(60):
        mean, std = at(ctrl.t)
        ctrl.forecast = _Forecast(mean, std, True)
        ctrl.act_measured(_measure(ctrl, V2_LANDING_CONFIG.hold_height))  # still high: abortable
        if ctrl.phase == "drop" and "commit" not in state:
            state["commit"] = ctrl.t
        phases.append(ctrl.phase)
    assert "commit" in state
    assert ctrl.aborts == 1 and phases[-1] == "hold"
    assert phases.index("drop") < len(phases) - 1 - phases[::-1].index("drop")  # dropped, then held


def test_unusable_forecast_falls_back_only_late() -> None:
    def implausible(t: float) -> tuple[np.ndarray, np.ndarray]:
        return _forecast(lambda h: np.full_like(h, -1.0))  # 57 deg of pitch: not a deck

    ctrl, phases = _run(implausible, 40)
    assert not ctrl.usable() and "drop" not in phases  # before fallback_time: waits


def test_policy_by_name_needs_the_forecast() -> None:
    import gymnasium as gym

    import ihrcf_env
    from ihrcf_env.experiments.policies import PolicyError, make_policy

    env = gym.make(ihrcf_env.LANDING_V2_ID, level="calm")
    try:
        with pytest.raises(PolicyError, match="scripted-forecast.*deck_forecast"):
            make_policy("scripted-forecast", env)
    finally:
        env.close()


def test_closed_loop_on_calm_flies_on_its_own_forecast() -> None:
    import ihrcf_env
    from ihrcf_env.control.forecast_landing import ForecastLanding
    from ihrcf_env.experiments.policies import make_env_for

    env, policy = make_env_for(ihrcf_env.LANDING_V2_ID, {"level": "calm"}, "scripted-forecast")
    try:
        assert isinstance(policy, ForecastLanding)
        ctrl = policy.controller
        assert isinstance(ctrl, ForecastLandingController)
        obs, info = env.reset(seed=500)
        policy.reset()
        usable_at = None
        for _ in range(600):
            action = policy.act(obs)
            assert action.shape == (4,) and np.all(np.isfinite(action)) and np.all(np.abs(action) <= 1.0)
            if usable_at is None and ctrl.usable():
                usable_at = ctrl.t
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        # it commits only on a usable forecast, or on the motion now after the fallback time
        if ctrl.commit_time is not None:
            assert (usable_at is not None and ctrl.commit_time >= usable_at) or (
                ctrl.commit_time >= ctrl.commit.fallback_time
            )
        assert info.get("outcome") in ("success", "flying", "crash")
    finally:
        env.close()
