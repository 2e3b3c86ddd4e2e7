"""The camera's latency ring and burst dropout (ihrcf_env.fast.frames) against DelayLine and
CameraDropout, float64."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from ihrcf_env.fast.frames import (
    STATUS_NO_FRAME,
    dropout_params,
    dropout_step,
    pipe_deliver,
    pipe_init,
    pipe_push,
    pipe_size,
)
from ihrcf_env.sim.faults import CameraDropout
from ihrcf_env.sim.sensors.base import tag_status_code
from ihrcf_env.sim.sensors.timing import NO_FRAME_YET, DelayLine

PHYSICS_HZ = 240


def run_pipe(latency: float, substeps: int, every: int, steps: int, seed: int):
    rng = np.random.default_rng(seed)
    corners = rng.uniform(0.0, 640.0, (steps, 4, 2))
    status = rng.integers(0, 12, steps).astype(np.int32)
    ticks = np.arange(steps, dtype=np.int32) * substeps
    expose = np.arange(steps) % every == 0
    lat_ticks = latency * PHYSICS_HZ
    size = pipe_size(lat_ticks, every * substeps)

    def body(pipe, x):
        tick, c, s, e = x
        pipe = pipe_deliver(pipe_push(pipe, tick, c, s, e), tick, lat_ticks)
        return pipe, (pipe.held_tick, pipe.held_corners, pipe.held_status, jnp.sum(pipe.exposed >= 0))

    run = jax.jit(lambda xs: jax.lax.scan(body, pipe_init(size), xs)[1])
    got = [np.asarray(a) for a in run((ticks, corners, status, expose))]
    line = DelayLine(latency, PHYSICS_HZ)
    held_tick, held = -1, None
    for k in range(steps):
        if expose[k]:
            line.push(int(ticks[k]), {"c": corners[k], "s": status[k]})
        for t, r in line.deliver(int(ticks[k])):
            held_tick, held = t, r
        assert got[0][k] == held_tick, (k, latency)
        assert got[3][k] == len(line)
        if held is None:
            assert got[2][k] == STATUS_NO_FRAME
        else:
            assert np.array_equal(got[1][k], held["c"]) and got[2][k] == held["s"]
    return got


@pytest.mark.parametrize(
    ("latency", "substeps", "every"),
    [(0.0, 4, 1), (0.05, 4, 2), (1.0 / 60.0, 4, 1), (0.12, 2, 3), (0.2, 4, 1), (0.0125, 8, 1)],
)
def test_pipe_matches_delay_line(latency: float, substeps: int, every: int) -> None:
    got = run_pipe(latency, substeps, every, 90, int(latency * 1e4) + every)
    assert np.any(got[0] >= 0)


def test_no_frame_status_is_the_readings() -> None:
    assert STATUS_NO_FRAME == tag_status_code(NO_FRAME_YET)


def test_pipe_size_validation() -> None:
    assert pipe_size(0.0, 4) == 1
    assert pipe_size(12.0, 4) == 4
    with pytest.raises(ValueError, match="period_ticks"):
        pipe_size(1.0, 0)


@pytest.mark.parametrize(("loss_rate", "mean_burst"), [(0.05, 3.0), (0.3, 2.0), (0.0, 1.0), (0.5, 1.0)])
def test_dropout_matches_camera_dropout(loss_rate: float, mean_burst: float) -> None:
    n = 400
    u = np.random.default_rng(11).random(n)
    ref = CameraDropout(loss_rate, mean_burst)
    ref.reset(np.random.default_rng(0))
    want = []
    gen = np.random.default_rng(11)  # one uniform per frame: the same as u
    for _ in range(n):
        out = ref.apply({"tag_corners": np.ones((4, 2))}, 0.0, 0.1, gen)
        want.append(not bool(out["tag_detected"]) if "tag_detected" in out else False)
    params = dropout_params(loss_rate, mean_burst)

    def body(c, x):
        bad, started = dropout_step(c[0], c[1], x, params)
        return (bad, started), bad

    _, got = jax.jit(lambda us: jax.lax.scan(body, (jnp.array(False), jnp.array(False)), us))(u)
    assert np.asarray(got).tolist() == want
    if 0.0 < loss_rate:
        assert 0 < sum(want) < n
