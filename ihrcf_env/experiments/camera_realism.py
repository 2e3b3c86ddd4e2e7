"""The realistic camera at the paper's 1 m hover: what it costs per frame, and the README's example frame.

* :func:`realism_cost_ms`: the realistic camera's added time per frame over the ideal one (the
  benchmark command prints it);
* :func:`save_realistic_example`: writes ``examples/figures/camera_realistic.png``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from ihrcf_env.config.sensors import CameraConfig
from ihrcf_env.sim.sensors.camera import DownCamera


def _hover_world(width: int, height: int, frames: int, camera: CameraConfig | None = None) -> Any:
    """A world at the paper's experiment: drone 1 m above the deck on the "paper" profile, 20 Hz."""
    from ihrcf_env.config.world import WorldConfig
    from ihrcf_env.core.profiles import paper_profile
    from ihrcf_env.sim.world import World

    world = World(
        WorldConfig(camera=camera if camera is not None else CameraConfig(width=width, height=height))
    )
    try:
        world.reset(paper_profile(), horizon_s=frames / world.config.control_hz + 2.0, altitude=1.0)
    except BaseException:
        world.close()
        raise
    return world


def realism_cost_ms(frames: int = 60, width: int = 512, height: int = 512, seed: int = 0) -> dict[str, float]:
    """What the realistic camera adds per frame over the ideal one, at the paper's 1 m hover.

    One world at the hover (``"paper"`` profile, 20 Hz, velocity hold); every control step both an
    ideal and a realistic camera (same client, same pose) read a frame, in alternating order, timed
    with ``time.perf_counter`` (3 warm-up frames not counted). Returns mean and median ms per frame
    of each (``ideal_ms``, ``realistic_ms``, ``*_median_ms``), their difference ``added_ms`` /
    ``added_median_ms``, the realistic post-processing alone (``processing_ms``: background, blur,
    vignetting, noise) and ``frames``.
    The figures depend on the machine's load: OpenCV's threads compete with other processes.
    """
    if frames < 1:
        raise ValueError(f"frames must be >= 1, got {frames!r}")
    world = _hover_world(width, height, frames + 5)
    try:
        rng = np.random.default_rng(seed)
        ideal = DownCamera(world.client, CameraConfig(width=width, height=height), world.config.rig)
        real = DownCamera(
            world.client, CameraConfig(width=width, height=height, quality="realistic"), world.config.rig
        )
        real.reset(rng)
        imager = real.imager
        assert imager is not None
        process = imager.process
        spent = [0.0]

        def timed_process(*args: Any) -> NDArray[np.uint8]:
            t = time.perf_counter()
            out = process(*args)
            spent[0] += time.perf_counter() - t
            return out

        setattr(imager, "process", timed_process)  # noqa: B010 (time the post-processing alone)
        t_ideal: list[float] = []
        t_real: list[float] = []
        for k in range(frames + 3):
            world.step()
            world.deck.update_visuals()
            state = world.sensing.body_state()
            order = (ideal, real) if k % 2 == 0 else (real, ideal)
            for cam in order:
                t0 = time.perf_counter()
                cam.read(state, 0.05, rng)
                dt = time.perf_counter() - t0
                if k >= 3:  # warm-up frames are not counted
                    (t_ideal if cam is ideal else t_real).append(dt)
            if k == 2:
                spent[0] = 0.0
    finally:
        world.close()
    ti, tr = np.array(t_ideal) * 1e3, np.array(t_real) * 1e3
    return {
        "frames": float(frames),
        "ideal_ms": float(ti.mean()),
        "realistic_ms": float(tr.mean()),
        "added_ms": float(tr.mean() - ti.mean()),
        "ideal_median_ms": float(np.median(ti)),
        "realistic_median_ms": float(np.median(tr)),
        "added_median_ms": float(np.median(tr) - np.median(ti)),
        "processing_ms": spent[0] * 1e3 / frames,
    }


def save_realistic_example(
    path: str | Path = "examples/figures/camera_realistic.png",
    seed: int = 0,
    steps: int = 40,
    size: int = 384,
) -> Path:
    """Write one realistic 512x512 frame of the paper's 1 m hover (after ``steps`` control steps of
    an episode seeded with ``seed``) as a PNG at ``path``, resized to ``size`` px (``INTER_AREA``;
    sensor noise does not compress: 512 px would be ~370 KB); returns the path. Regenerates the
    README figure ``examples/figures/camera_realistic.png``."""
    world = _hover_world(512, 512, steps + 5, CameraConfig(quality="realistic"))
    try:
        rng = np.random.default_rng(seed)
        world.reset_random(rng)
        for _ in range(steps):
            world.step()
        image = world.sensing.read_sensors(rng, ("camera",))["image"]
    finally:
        world.close()
    if size != image.shape[1]:
        image = cv2.resize(image, (size, size), interpolation=cv2.INTER_AREA)
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(out), cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9]):
        raise OSError(f"could not write {out}")
    return out


__all__ = [
    "realism_cost_ms",
    "save_realistic_example",
]
