"""Shared fixtures: envs and worlds that close themselves, counters of what an env may leak, and
helpers several test files use (import them with ``from conftest import ...``)."""

from __future__ import annotations

import importlib.util
import signal
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env.core.calibration import Calibration
from ihrcf_env.sim.world import World

# The Ctrl-C tests send SIGINT to the commands they start. A process started with SIGINT ignored
# (a background job of a non-interactive shell, nohup) passes that on to every child, which would
# then never see the signal: the suite makes its own SIGINT the default again, so the children
# start with the default disposition (a handler, unlike an ignore, is reset by exec).
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

#: Highest PyBullet client id probed when counting connected clients.
_MAX_CLIENTS = 256

#: The example scripts (not a package: :func:`example` imports them by path).
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def connected_clients() -> int:
    """How many PyBullet clients are connected in this process."""
    return sum(bool(p.isConnected(physicsClientId=i)) for i in range(_MAX_CLIENTS))


def example(name: str) -> ModuleType:
    """Import ``examples/<name>.py`` under a private module name (the examples are scripts)."""
    spec = importlib.util.spec_from_file_location(f"_example_{name}", EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def temp_dirs() -> set[str]:
    """The env's temporary directories that exist now."""
    return {d.name for d in Path(tempfile.gettempdir()).glob("ihrcf_env_*")}


@pytest.fixture
def make_env() -> Iterator[Callable[..., gym.Env]]:
    """``make_env(id, **options)``: ``gym.make`` whose envs are closed when the test ends, pass or fail."""
    envs: list[gym.Env] = []

    def make(env_id: str, **options: Any) -> gym.Env:
        env = gym.make(env_id, **options)
        envs.append(env)
        return env

    yield make
    for env in envs:
        env.close()


@pytest.fixture
def make_v1(make_env: Callable[..., gym.Env]) -> Callable[..., gym.Env]:
    """``make_v1(**options)``: DeckLanding-v1 through ``make_env`` (closed when the test ends), with a
    60 s horizon unless ``horizon_s`` is given."""
    return lambda **options: make_env(ihrcf_env.LANDING_V1_ID, **{"horizon_s": 60.0, **options})


@pytest.fixture
def private_tmp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A temporary-files folder of this test alone (``tempfile`` writes there), so counting the
    env's temp dirs sees this process only, not other test runs sharing the system's folder."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


@pytest.fixture
def no_leaks(private_tmp: Path) -> Iterator[None]:
    """Fails the test if it leaves a PyBullet client connected or an env temp dir behind."""
    clients, dirs = connected_clients(), temp_dirs()
    yield
    assert connected_clients() <= clients, "a PyBullet client was left connected"
    assert temp_dirs() <= dirs, "an env temporary directory was left behind"


@pytest.fixture
def closing() -> Iterator[Callable[[Any], Any]]:
    """``closing(thing)``: returns ``thing`` and calls its ``close()`` when the test ends, pass or
    fail (for envs and wrappers built without ``gym.make``)."""
    things: list[Any] = []

    def register(thing: Any) -> Any:
        things.append(thing)
        return thing

    yield register
    for thing in things:
        thing.close()


@pytest.fixture
def make_world(closing: Callable[[Any], Any]) -> Callable[..., World]:
    """``make_world(config=None)``: ``World(config)`` closed when the test ends, pass or fail."""
    return lambda config=None: closing(World(config))


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0) -> list[Any]:
    """Reset with ``seed``, then up to ``steps`` seeded random actions (uniform in [-0.3, 0.3]):
    every observation, drone position (world frame, m) and reward, until the episode terminates."""
    rng = np.random.default_rng(action_seed)
    obs, info = env.reset(seed=seed)
    seq = [obs, info["drone_position_world"]]
    for _ in range(steps):
        obs, reward, terminated, _, info = env.step(rng.uniform(-0.3, 0.3, 4).astype(np.float32))
        seq += [obs, info["drone_position_world"], reward]
        if terminated:
            break
    return seq


def descend(
    env: gym.Env, options: dict[str, Any], vz: float = 0.3, steps: int = 400
) -> tuple[bool, bool, dict]:
    """Reset (seed 0, ``options``) and command a vertical descent at ``vz`` (m/s, > 0 down) until
    the episode ends: (terminated, truncated, info) of the last step; fails if it never ends."""
    env.reset(seed=0, options=options)
    for _ in range(steps):
        _, _, terminated, truncated, info = env.step(np.array([0.0, 0.0, -vz, 0.0], np.float32))
        if terminated or truncated:
            return terminated, truncated, info
    raise AssertionError("no touchdown")


def calibration_fields(cal: Calibration) -> dict[str, Any]:
    """The constructor arguments that rebuild ``cal`` (to build it again with one of them changed)."""
    return dict(
        image_width=cal.image_width,
        image_height=cal.image_height,
        fov=cal.fov,
        rig=cal.rig,
        tables=cal.tables,
        K=cal.K,
        dist=cal.dist,
    )


def same(a: Any, b: Any) -> bool:
    """Bitwise equality of two observations (arrays, or dicts of them, nested)."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return bool(np.array_equal(a, b))


def same_runs(a: list[Any], b: list[Any]) -> bool:
    """Two :func:`rollout` sequences are equal, step by step (a shorter one is not)."""
    return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))


def _random_policy() -> Any:
    """A small GRU policy (5 inputs of an observation of 8) of random weights."""
    from ihrcf_env.control.gru_policy import WEIGHTS, GruPolicy

    rng = np.random.default_rng(0)
    sizes = {"D": 5, "E": 6, "H": 4, "3H": 12, "F": 3, "A": 4}
    w = {k: rng.normal(scale=0.5, size=tuple(sizes[x] for x in dims)) for k, dims in WEIGHTS.items()}
    w["std"] = np.abs(w["std"]) + 0.5
    return GruPolicy(w, [1, 2, 3, 4, 5], 8)


def policy_header(**fields: object) -> str:
    """A policy file's JSON header (of :func:`write_policy`'s weights) with ``fields`` changed."""
    import json

    return json.dumps({"format": 1, "inputs": [1, 2, 3, 4, 5], "obs_size": 8, "meta": {}, **fields})


def write_policy(path: Path, header: str | None, drop: str | None = None) -> Path:
    """A GRU policy file at ``path`` with this ``header`` (None: none) and without the weight ``drop``."""
    payload = {k: v for k, v in _random_policy().weights.items() if k != drop}
    if header is not None:
        payload["header"] = np.array(header)
    with open(path, "wb") as f:
        np.savez(f, **payload)
    return path


def corrupt_policy_files(folder: Path) -> dict[str, tuple[Path, str]]:
    """Corrupt policy files by kind -> (path, a word the error must contain)."""
    good = write_policy(folder / "good.npz", policy_header())
    data = good.read_bytes()
    files: dict[str, tuple[Path, str]] = {}

    def put(kind: str, content: bytes, word: str) -> None:
        path = folder / f"{kind}.npz"
        path.write_bytes(content)
        files[kind] = (path, word)

    put("truncated", data[: len(data) // 2], "npz")
    put("empty", b"", "npz")
    put("text", b"# a text file\n1 2 3\n", "npz")
    deep = '{"format": 1, "inputs": [1], "obs_size": 8, "meta": ' + "[" * 100_000 + "]" * 100_000 + "}"
    cases = {
        "no_header": (None, None, "header"),
        "no_weight": (policy_header(), "w_o", "w_o"),
        "no_inputs": ('{"format": 1, "obs_size": 8}', None, "inputs"),
        "no_format": ('{"inputs": [1], "obs_size": 8}', None, "format"),
        "obs_size_inf": ('{"format": 1, "inputs": [1], "obs_size": 1e999}', None, "obs_size"),
        "obs_size_text": (policy_header(obs_size="8"), None, "obs_size"),
        "inputs_text": (policy_header(inputs="12345"), None, "inputs"),
        "inputs_floats": (policy_header(inputs=[1.5, 2.0]), None, "inputs"),
        "meta_list": (policy_header(meta=[1, 2]), None, "meta"),
        "header_list": ("[1, 2, 3]", None, "header"),
        "header_not_json": ("{format: 1", None, "JSON"),
        "deep": (deep, None, "nested"),
        "inputs_out_of_range": (policy_header(inputs=[1, 2, 3, 4, 99]), None, "inputs"),
    }
    for kind, (header, drop, word) in cases.items():
        files[kind] = (write_policy(folder / f"{kind}.npz", header, drop), word)
    text_weights = folder / "text_weights.npz"
    payload = dict(_random_policy().weights)
    payload["w_e"] = np.array(["a", "b"])
    np.savez(text_weights, header=np.array(policy_header()), **payload)
    files["text_weights"] = (text_weights, "w_e")
    return files
