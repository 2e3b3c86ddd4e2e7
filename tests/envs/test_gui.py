"""render_mode="human" (PyBullet's GUI) where a display exists: under a virtual X server.

Runs in a subprocess under ``xvfb-run -a`` (Debian: ``apt-get install xvfb``); skipped where
xvfb-run is missing. ``LIBGL_ALWAYS_SOFTWARE=1`` pins Mesa's software renderer (llvmpipe), which
is what Xvfb offers anyway; PyBullet's GUI works under Xvfb with or without it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap

import pytest

GUI_SCRIPT = """
import warnings
import gymnasium as gym
import numpy as np
from gymnasium.utils.env_checker import check_env
from gymnasium.utils.passive_env_checker import env_render_passive_checker
import ihrcf_env

warnings.simplefilter("ignore")
ID = "ihrcf_env/DeckHoverRaw-v0"
SMALL = {"camera_width": 64, "camera_height": 64}

env = gym.make(ID, render_mode="human", **SMALL)
obs, info = env.reset(seed=0)
assert obs["image"].shape == (64, 64, 3)
for _ in range(5):
    obs, reward, terminated, truncated, info = env.step(np.array([0.1, 0.0, 0.0, 0.1], np.float32))
assert env.render() is None
env_render_passive_checker(env.unwrapped)
try:  # PyBullet allows one GUI per process: a second human env is refused before connecting
    gym.make(ID, render_mode="human", **SMALL)
    raise SystemExit("a second human env was allowed")
except RuntimeError as e:
    assert "one" in str(e), e
check_env(env.unwrapped, skip_render_check=True, skip_close_check=True)  # both re-make "human"
env.close()
env.close()

# the full checker, render check included: it makes the env again in every render mode
# ("human" among them), resets and renders each
env = gym.make(ID, render_mode="rgb_array", chase_size=(80, 60), **SMALL)
check_env(env.unwrapped)
env.close()
print("GUI OK")
"""


# CI sets IHRCF_REQUIRE_GUI_TEST=1 (and installs xvfb): there the test must run, never skip.
@pytest.mark.skipif(
    shutil.which("xvfb-run") is None and not os.environ.get("IHRCF_REQUIRE_GUI_TEST"),
    reason="xvfb-run not installed (apt-get install xvfb)",
)
def test_human_render_mode_and_check_env_with_render_check_under_xvfb():
    # -noreset: by default Xvfb resets when its last client disconnects, and a GUI connecting during
    # that reset (after the display probe, or when check_env re-makes the "human" env) is refused
    # with "cannot connect to X server" -- measured as an intermittent failure under load
    env = {**os.environ, "LIBGL_ALWAYS_SOFTWARE": "1"}
    out = subprocess.run(
        [
            "xvfb-run",
            "-a",
            "-s",
            "-noreset -screen 0 1280x1024x24",
            sys.executable,
            "-c",
            textwrap.dedent(GUI_SCRIPT),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert out.returncode == 0, (out.stdout[-3000:], out.stderr[-3000:])
    assert "GUI OK" in out.stdout
