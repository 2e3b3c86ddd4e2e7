"""The one rollout and the accuracy experiment built on it."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest

from ihrcf_env.core.metrics import table2_text
from ihrcf_env.experiments.accuracy import HOVER_START, accuracy, hover_rollout
from ihrcf_env.experiments.rollout import Recording, rollout


def _recording() -> Recording:
    """Three frames: IHRCF 2 cm off in y and 0.02 rad off in yaw across the wrap, ATDA exact but
    invalid (and wildly wrong) in the last frame."""
    gt_pos = np.array([[0.0, 0.0, -1.0]] * 3)
    gt_eul = np.array([[0.0, 0.0, -np.pi + 0.01]] * 3)
    atda_pos = gt_pos.copy()
    atda_pos[2] = (5.0, 5.0, 5.0)
    return Recording(
        time=np.array([0.05, 0.1, 0.15]),
        position={"gt": gt_pos, "ihrcf": gt_pos + (0.0, 0.02, 0.0), "atda": atda_pos},
        euler={"gt": gt_eul, "ihrcf": gt_eul - (0.0, 0.0, 0.02), "atda": gt_eul.copy()},
        valid={"ihrcf": np.ones(3, bool), "atda": np.array([True, True, False])},
        ranges=np.ones((3, 4)),
        ranges_valid=np.ones((3, 4), bool),
        command=np.zeros((3, 4)),
        drone_minus_deck=np.zeros((3, 3)),
        heading_error=np.zeros(3),
        wall_time=1.0,
    )


def test_recording_scores_each_estimator_against_ground_truth() -> None:
    res = _recording()
    e = res.pose_errors("ihrcf")
    assert np.allclose(e, [0.0, 0.02, 0.0, 0.0, 0.0, -np.degrees(0.02)])  # estimate minus truth, wrapped
    stats = res.error_stats()
    assert stats["ihrcf"].mae[1] == pytest.approx(0.02) and stats["ihrcf"].invalid == 0
    assert np.allclose(stats["atda"].mae, 0.0) and stats["atda"].invalid == 1
    assert np.all(np.isnan(res.pose_errors("atda")[2]))
    table = table2_text(stats)
    assert "ATDA 1/3" in table and "IHRCF 0/3" in table


def test_rollout_stops_where_the_episode_ends(make_env) -> None:
    env = make_env("ihrcf_env/DeckHover-v0", deck_profile="static", keep_image=False, max_episode_steps=3)
    calls = []
    rec = rollout(env, 5, lambda obs: calls.append(obs) or np.zeros(4), seed=0, options=HOVER_START)
    assert rec.n == 3 and len(calls) == 3 and rec.ended_early == "truncated"
    assert np.allclose(np.diff(rec.time), 1 / 20) and np.all(rec.valid["ihrcf"])
    assert np.allclose(rec.position["gt"][:, :2], 0.0, atol=0.01)  # HOVER_START: straight over the deck
    assert np.allclose(rec.command, 0.0)


def test_accuracy_scores_the_hover() -> None:
    stats = accuracy(6, env_kwargs={"deck_profile": "static"})
    for key in ("atda", "ihrcf"):
        assert stats[key].frames == 6 and stats[key].invalid == 0
        assert np.all(stats[key].mae <= stats[key].peak + 1e-12)  # equal on a static deck, bar rounding
    assert stats["ihrcf"].mae[2] < 0.005  # m


def test_hover_rollout_is_the_paper_start(make_env) -> None:
    env = make_env("ihrcf_env/DeckHover-v0", deck_profile="static", keep_image=False)
    rec = hover_rollout(env, 2)
    assert rec.n == 2
    assert rec.position["gt"][0] == pytest.approx([0.0, 0.0, -1.0], abs=0.02)


def test_hover_rollout_at_another_altitude(make_env) -> None:
    env = make_env("ihrcf_env/DeckHover-v0", deck_profile="static", keep_image=False)
    rec = hover_rollout(env, 2, altitude=2.0)
    assert rec.position["gt"][0] == pytest.approx([0.0, 0.0, -2.0], abs=0.02)
    assert rec.valid["ihrcf"].all()  # the tag is seen and estimated from 2 m too


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize(("stream", "shown"), [(_Terminal, True), (io.StringIO, False)])
def test_progress_bar_only_on_a_terminal(make_env, stream: type[io.StringIO], shown: bool) -> None:
    env = make_env("ihrcf_env/DeckHover-v0", deck_profile="static", keep_image=False)
    err = stream()
    with contextlib.redirect_stderr(err):
        rollout(env, 2, seed=0, options=HOVER_START, progress=True)
    assert ("100%" in err.getvalue()) is shown


def test_hover_rollout_can_hold_over_the_tag_horizontally(make_env) -> None:
    env = make_env(
        "ihrcf_env/DeckHover-v0", deck_profile="static", keep_image=False, autopilot_feedback="estimated"
    )
    rec = hover_rollout(env, 40, seed=3, track="fused")
    assert np.all(rec.command[:, 2:] == 0.0)  # altitude and heading stay on the autopilot
    assert np.any(rec.command[:, :2] != 0.0)  # the fused estimate steers x/y once it has converged
    assert rec.valid["fused"][-1]
