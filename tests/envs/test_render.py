"""The env's renderer (:class:`~ihrcf_env.envs.render.EnvRenderer`): the chase view the env's
``render()`` returns, the one-GUI-per-process claim and its release."""

from __future__ import annotations

import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.envs import render as render_module
from ihrcf_env.envs.render import EnvRenderer


def test_env_render_is_its_renderers_chase_view(make_env) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, render_mode="rgb_array", camera=False, chase_size=(64, 48))
    env.reset(seed=0)
    base = env.unwrapped
    assert isinstance(base.renderer, EnvRenderer) and base.renderer.world is base.world
    frame = env.render()
    assert frame.shape == (48, 64, 3) and frame.dtype == np.uint8 and frame.std() > 0
    assert np.array_equal(frame, base.renderer.chase_view())
    env.close()
    assert base.renderer.released and base.renderer.world is None
    with pytest.raises(RuntimeError, match="closed"):
        env.render()


def test_no_render_mode_renders_nothing(make_env) -> None:
    env = make_env(ihrcf_env.HOVER_RAW_ID, camera=False)
    env.reset(seed=0)
    assert env.render() is None


def test_one_gui_claim_per_process_until_released(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(render_module, "require_gui_display", lambda: None)
    monkeypatch.setattr(EnvRenderer, "_gui_owner", None)
    first = EnvRenderer("human", (64, 48))
    with pytest.raises(RuntimeError, match="one"):
        EnvRenderer("human", (64, 48))
    EnvRenderer("rgb_array", (64, 48))  # offscreen: no claim
    first.release()
    first.release()  # twice is fine
    second = EnvRenderer("human", (64, 48))
    assert EnvRenderer._gui_owner is second
    second.release()
    assert EnvRenderer._gui_owner is None


def test_a_renderer_without_a_world_says_so() -> None:
    with pytest.raises(RuntimeError, match="no world"):
        EnvRenderer("rgb_array", (64, 48)).render()
    EnvRenderer(None, (64, 48)).follow()  # nothing to follow without a GUI
