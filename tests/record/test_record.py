"""Rerun recordings: a short episode written, read back and checked against the episode; the
wrapper off; bad input (paths, ids, options, Rerun missing)."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env import LANDING_V2_ID
from ihrcf_env.record import ENTITIES, RecordEpisode, RecordingPathError, RerunMissingError
from ihrcf_env.record import _rerun as rerun_import

rr = pytest.importorskip("rerun")
pa = pytest.importorskip("pyarrow")
from rerun.chunk import RrdReader  # noqa: E402

STEPS = 12


def _env(**kw: Any) -> gym.Env:
    return gym.make(LANDING_V2_ID, camera_model="projected", max_episode_steps=STEPS, **kw)


def _read(path: Path) -> dict[str, dict[str, list[Any]]]:
    """entity path -> column -> values (non-static chunks merged, rows in time order)."""
    out: dict[str, dict[str, list[Any]]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        ent = out.setdefault(str(chunk.entity_path).lstrip("/"), {})
        for k in batch.schema.names:
            if k == "log_time":
                continue
            col = batch.column(k)
            values = (
                [v * 1e-9 for v in col.cast(pa.int64()).to_pylist()] if k == "sim_time" else col.to_pylist()
            )
            ent.setdefault(k, []).extend(values)
    return out


def _at(entity: dict[str, list[Any]], column: str, t: float) -> Any:
    """The value of ``column`` logged at simulated time ``t`` (s)."""
    times = entity["sim_time"]
    i = int(np.argmin(np.abs(np.asarray(times) - t)))
    assert abs(times[i] - t) < 1e-6, (t, times)
    return entity[column][i]


def _fly(env: gym.Env, seed: int = 3) -> list[dict[str, Any]]:
    infos = []
    obs, info = env.reset(seed=seed)
    infos.append(info)
    rng = np.random.default_rng(0)
    while True:
        obs, _, term, trunc, info = env.step(rng.uniform(-0.3, 0.3, 4).astype(np.float32))
        infos.append(info)
        if term or trunc:
            return infos


def test_recording_holds_the_episode(tmp_path: Path) -> None:
    env = RecordEpisode(_env(), tmp_path / "ep-{seed}.rrd")
    infos = _fly(env)
    env.close()
    out = tmp_path / "ep-3.rrd"
    assert env.written == [out] and out.stat().st_size > 0
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary left
    data = _read(out)
    names = env.get_wrapper_attr("estimator_names")
    for path in set(ENTITIES) - {"camera/corners", "camera/tag"}:  # corners: only once detected
        assert path in data, path
    for name in names:
        assert f"estimates/{name}/valid" in data
    assert "reward/progress" in data
    # drone, deck and truth at a time in the middle of the episode
    info = infos[STEPS // 2]
    t = float(info["time"])
    drone = _at(data["world/drone"], "Transform3D:translation", t)
    np.testing.assert_allclose(np.ravel(drone), info["drone_position_world"], atol=1e-5)
    deck_q = _at(data["world/deck"], "Transform3D:quaternion", t)
    np.testing.assert_allclose(np.ravel(deck_q), info["deck_quaternion_world"], atol=1e-6)
    truth = _at(data["truth/position"], "Scalars:scalars", t)
    np.testing.assert_allclose(truth, info["deck_position_body"], atol=1e-9)
    rewards = [_at(data["reward/progress"], "Scalars:scalars", float(i["time"]))[0] for i in infos[1:]]
    np.testing.assert_allclose(rewards, [i["reward_progress"] for i in infos[1:]])
    assert len(data["world/drone"]["sim_time"]) == len(infos)
    # the truth in the body frame and the two world poses agree (what the 3D view draws)
    from scipy.spatial.transform import Rotation

    r = Rotation.from_quat(info["drone_quaternion_world"])
    deck_world = np.asarray(info["drone_position_world"]) + r.apply(info["deck_position_body"])
    np.testing.assert_allclose(deck_world, info["deck_position_world"], atol=1e-3)
    events = data["events/outcome"]["TextLog:text"]
    assert events == [["outcome: timeout"]] if infos[-1]["outcome"] == "flying" else events


def test_keep_skips_episodes_and_off_adds_nothing(tmp_path: Path) -> None:
    env = RecordEpisode(_env(), tmp_path / "ep.rrd", keep=lambda info: info.get("outcome") == "success")
    _fly(env)
    env.close()
    assert env.written == [] and list(tmp_path.iterdir()) == []
    base = _env()
    off = RecordEpisode(base, tmp_path / "never.rrd", enabled=False)
    a = _fly(off, seed=5)
    b = _fly(_env(), seed=5)
    off.close()
    assert list(tmp_path.iterdir()) == []
    assert [i["time"] for i in a] == [i["time"] for i in b]
    np.testing.assert_array_equal(a[-1]["drone_position_world"], b[-1]["drone_position_world"])
    assert not hasattr(off, "_geometry")  # off: nothing was built


def test_bad_paths(tmp_path: Path) -> None:
    with pytest.raises(RecordingPathError, match="folder"):
        RecordEpisode(_env(), tmp_path)
    with pytest.raises(RecordingPathError, match="path"):
        RecordEpisode(_env())
    with pytest.raises(RecordingPathError, match="seed"):
        RecordEpisode(_env(), tmp_path / "{nope}.rrd")
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        with pytest.raises(RecordingPathError, match="cannot write"):
            RecordEpisode(_env(), ro / "x.rrd")


def test_rerun_missing(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: Any) -> None:
    real = rerun_import.importlib.import_module

    def missing(name: str, package: str | None = None) -> Any:
        if name == "rerun" or name.startswith("rerun."):
            raise ImportError(f"No module named {name!r}")
        return real(name, package)

    monkeypatch.setattr(rerun_import.importlib, "import_module", missing)
    with pytest.raises(RerunMissingError, match=r'pip install "ihrcf-env\[viewer\]"'):
        RecordEpisode(_env(), tmp_path / "x.rrd")
    RecordEpisode(_env(), tmp_path / "x.rrd", enabled=False).close()  # off needs no Rerun
    from ihrcf_env.record.command import main

    with pytest.raises(SystemExit) as e:
        main(["--policy", "blind:0.3", "--out", str(tmp_path / "x.rrd")])
    assert e.value.code == 2
    assert "ihrcf-env[viewer]" in capsys.readouterr().err
    from ihrcf_env.cli.evaluate import main as evaluate

    with pytest.raises(SystemExit) as e:
        evaluate(["--policy", "blind:0.3", "--episodes", "1", "--record", str(tmp_path / "rec")])
    assert e.value.code == 2
    assert "ihrcf-env[viewer]" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--policy", "blind:0.3", "--out", "{dir}"], "folder"),
        (["--policy", "blind:0.3", "--env-id", "nope/Nope-v0", "--out", "{dir}/x.rrd"], "--env-id"),
        (["--policy", "blind:-1", "--out", "{dir}/x.rrd"], "--policy"),
        (["--policy", "blind:0.3", "--option", "bad", "--out", "{dir}/x.rrd"], "--option"),
        (["--policy", "blind:0.3"], "--out"),
        (["--policy", "blind:0.3", "--out", "{dir}/x.rrd", "--spawn"], "not allowed"),
    ],
)
def test_record_cli_usage_errors(tmp_path: Path, capsys: Any, argv: list[str], message: str) -> None:
    from ihrcf_env.record.command import main

    with pytest.raises(SystemExit) as e:
        main([a.replace("{dir}", str(tmp_path)) for a in argv])
    assert e.value.code == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_record_cli_writes_one_episode(tmp_path: Path, capsys: Any) -> None:
    from ihrcf_env.record.command import main

    out = tmp_path / "sub" / "land.rrd"
    argv = ["--policy", "scripted", "--env-id", LANDING_V2_ID, "--camera-model", "projected"]
    assert main([*argv, "--max-steps", "6", "--seed", "4", "--out", str(out)]) == 0
    assert re.match(r"seed +4 ", capsys.readouterr().out)
    data = _read(out)
    assert len(data["world/drone"]["sim_time"]) == 7  # reset + 6 steps
    assert "estimates/fused/valid" in data and "action" in data
    corners = [c for c in data["camera/corners"].get("Points2D:positions", []) if c]
    assert corners and all(len(c) == 4 for c in corners)  # the scripted approach sees the tag
    outlines = [s for s in data["camera/tag"].get("LineStrips2D:strips", []) if s]
    assert len(outlines) == len(corners) and outlines[0][0][0] == outlines[0][0][-1]


def test_evaluate_records_failures(tmp_path: Path, capsys: Any) -> None:
    from ihrcf_env.cli.evaluate import main

    argv = ["--policy", "blind:0.3", "--env-id", LANDING_V2_ID, "--camera-model", "projected"]
    assert main([*argv, "--max-steps", "4", "--episodes", "2", "--record", str(tmp_path / "rec")]) == 0
    names = sorted(p.name for p in (tmp_path / "rec").iterdir())
    assert names == ["DeckLanding-v2-seed0.rrd", "DeckLanding-v2-seed1.rrd"]  # timeouts are failures
    with pytest.raises(SystemExit) as e:
        main([*argv, "--record-all"])
    assert e.value.code == 2
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as e:
        main([*argv, "--record", str(tmp_path / "file")])
    assert e.value.code == 2
    assert "--record" in capsys.readouterr().err


def test_episode_log_images_and_estimates(tmp_path: Path) -> None:
    """The log alone (no env): a frame with an image, an estimate, the outcome; read back."""
    from ihrcf_env.core.estimators import PoseEstimate, SensorFrame
    from ihrcf_env.record import EpisodeLog, SceneGeometry

    geometry = SceneGeometry(0.8, 0.04, 0.4, np.zeros((4, 3)), np.zeros(3), np.eye(3) * 100, (64, 48), 4.0)
    log = EpisodeLog(geometry, ["mine"])
    image = np.full((48, 64, 3), 128, np.uint8)
    frame = SensorFrame(
        0.0, None, np.array([1.0, 1.0, np.nan, 1.0]), np.array([1, 1, 0, 1], bool), image=image
    )
    est = PoseEstimate(np.array([0.1, 0.2, -1.0]), np.zeros(3), np.eye(3), True, 0.001)
    truth = {"deck_position_body": np.array([0.1, 0.2, -1.5]), "deck_euler_body": np.zeros(3)}
    log.add_step({"time": 0.0, **truth}, frame=frame, estimates={"mine": est})
    log.add_step({"time": 0.05, "outcome": "crash", "crash_reason": "tilt", **truth}, action=[0, 0, 0, 0])
    log.end({"outcome": "crash", "crash_reason": "tilt"})
    rec = rr.RecordingStream("test")
    rec.save(tmp_path / "log.rrd")
    log.send(rec, rr)
    rec.flush()
    rec.disconnect()
    data = _read(tmp_path / "log.rrd")
    assert "camera/image" in data and "EncodedImage:blob" in data["camera/image"]
    assert _at(data["estimates/mine/position_error"], "Scalars:scalars", 0.0) == pytest.approx([0.5])
    assert _at(data["tof/valid"], "Scalars:scalars", 0.0) == [1.0, 1.0, 0.0, 1.0]
    assert _at(data["tof/ranges"], "Scalars:scalars", 0.0)[2] == 0.0  # NaN range: finite in the log
    assert data["events/outcome"]["TextLog:text"] == [["outcome: crash (tilt)"]]


def test_raw_env_readings_are_recorded(tmp_path: Path) -> None:
    """A raw env (Dict observation, no estimators): its ToF readings and corners are recorded."""
    env = RecordEpisode(
        gym.make("ihrcf_env/DeckHoverRaw-v0", camera_model="projected", max_episode_steps=4),
        tmp_path / "raw.rrd",
    )
    obs, _ = env.reset(seed=1)
    readings = [np.asarray(obs["ranges"], dtype=np.float64)]
    for _ in range(4):
        obs, *_ = env.step(env.action_space.sample() * 0)
        readings.append(np.asarray(obs["ranges"], dtype=np.float64))
    env.close()
    data = _read(tmp_path / "raw.rrd")
    got = np.array(data["tof/ranges"]["Scalars:scalars"])
    want = np.where(np.isfinite(readings), readings, 0.0)
    np.testing.assert_allclose(got, want)
    assert not any(k.startswith("estimates/") for k in data)
