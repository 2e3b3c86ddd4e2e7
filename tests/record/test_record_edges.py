"""The recorder's edges: what it refuses to write over, a missing viewer, a template an unseeded
episode cannot fill, a failing write (a file-size limit standing in for a full disk), bad ``path``
and ``keep`` arguments; and the command lines' empty paths."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest

import ihrcf_env  # noqa: F401  (registers the envs)
from ihrcf_env import LANDING_V2_ID
from ihrcf_env.record import (
    RecordEpisode,
    RecordingPathError,
    RecordingWriteError,
    ViewerMissingError,
    check_recording_path,
)
from ihrcf_env.record import wrapper as record_wrapper

pytest.importorskip("rerun")

STEPS = 4


def _env() -> gym.Env:
    return gym.make(LANDING_V2_ID, camera_model="projected", max_episode_steps=STEPS)


def _fly(env: gym.Env, seed: int | None = 3) -> dict[str, Any]:
    env.reset(seed=seed)
    while True:
        *_, term, trunc, info = env.step(env.action_space.sample() * 0)
        if term or trunc:
            return info


def test_a_fifo_is_refused_and_left_alone(tmp_path: Path, capsys: Any) -> None:
    """An existing special file (a FIFO here; a device node alike) is refused with exit status 2,
    before anything flies, and stays what it was."""
    from ihrcf_env.record.command import main

    fifo = tmp_path / "pipe.rrd"
    os.mkfifo(fifo)
    with pytest.raises(SystemExit) as e:
        main(["--policy", "blind:0.3", "--camera-model", "projected", "--out", str(fifo)])
    assert e.value.code == 2
    assert "--out" in capsys.readouterr().err
    assert fifo.is_fifo()
    with pytest.raises(RecordingPathError, match="not a regular file"):
        RecordEpisode(_env(), fifo)
    assert fifo.is_fifo() and sorted(p.name for p in tmp_path.iterdir()) == ["pipe.rrd"]


def test_a_template_reaching_a_special_file_is_refused_at_the_episode_end(tmp_path: Path) -> None:
    """A per-seed path that turns out to be a FIFO when the episode ends: refused, not replaced."""
    env = RecordEpisode(_env(), tmp_path / "ep-{seed}.rrd")
    os.mkfifo(tmp_path / "ep-3.rrd")
    with pytest.raises(RecordingPathError, match="not a regular file"):
        _fly(env, seed=3)
    env.close()
    assert (tmp_path / "ep-3.rrd").is_fifo()


def test_only_an_rrd_file_is_replaced(tmp_path: Path) -> None:
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me")
    with pytest.raises(RecordingPathError, match="not a recording"):
        check_recording_path(notes)
    old = tmp_path / "old.rrd"
    old.write_bytes(b"")
    assert check_recording_path(old) == old  # a recording is replaced
    fresh = tmp_path / "new-name"
    assert check_recording_path(fresh) == fresh  # a new file may have any name
    assert notes.read_text() == "keep me"


@pytest.mark.parametrize("value", ["", "  "])
def test_an_empty_path_is_named_as_empty(tmp_path: Path, capsys: Any, value: str) -> None:
    from ihrcf_env.cli.evaluate import main as evaluate
    from ihrcf_env.record.command import main

    with pytest.raises(RecordingPathError, match="empty"):
        check_recording_path(value)
    with pytest.raises(SystemExit) as e:
        main(["--policy", "blind:0.3", "--out", value])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "empty" in err and "'.'" not in err
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        with pytest.raises(SystemExit) as e:
            evaluate(["--policy", "blind:0.3", "--episodes", "1", "--record", value])
    finally:
        os.chdir(cwd)
    assert e.value.code == 2
    assert "--record" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_spawn_without_a_viewer_is_one_line_and_exit_2(
    tmp_path: Path, capsys: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No ``rerun`` on PATH nor beside the interpreter, none listening: refused before the env
    is made, in one line."""
    from ihrcf_env.record.command import main

    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(record_wrapper.sys, "executable", str(tmp_path / "python"))
    monkeypatch.setattr(record_wrapper, "VIEWER_PORT", 1)  # nothing listens on port 1
    made: list[str] = []
    monkeypatch.setattr(gym, "make", lambda *a, **k: made.append("env") or pytest.fail("env made"))
    with pytest.raises(SystemExit) as e:
        main(["--policy", "blind:0.3", "--spawn"])
    assert e.value.code == 2 and made == []
    err = capsys.readouterr().err.strip().splitlines()
    assert "--spawn" in err[-1] and "rerun" in err[-1] and "Traceback" not in "".join(err)
    monkeypatch.undo()
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(record_wrapper.sys, "executable", str(tmp_path / "python"))
    monkeypatch.setattr(record_wrapper, "_viewer_listening", lambda port=0: False)
    with pytest.raises(ViewerMissingError, match="PATH"):
        RecordEpisode(_env(), spawn=True)


def test_an_unseeded_template_is_refused_at_construction(tmp_path: Path) -> None:
    """``{seed:05d}`` cannot name an unseeded episode: refused when the wrapper is made, not at
    the episode's last step."""
    with pytest.raises(RecordingPathError, match="unseeded"):
        RecordEpisode(_env(), tmp_path / "ep-{seed:05d}.rrd")
    env = RecordEpisode(_env(), tmp_path / "ep-{seed}-{episode:03d}.rrd")
    _fly(env, seed=None)
    _fly(env, seed=2)
    env.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ep-2-001.rrd", "ep-none-000.rrd"]


def test_bad_path_and_keep_are_named(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="path"):
        RecordEpisode(_env(), 3)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="keep"):
        RecordEpisode(_env(), tmp_path / "x.rrd", keep=3)  # type: ignore[arg-type]
    env = RecordEpisode(_env(), tmp_path / "x.rrd", keep=lambda info: "no")  # type: ignore[arg-type,return-value]
    with pytest.raises(TypeError, match="keep must return a bool"):
        _fly(env)
    env.close()
    assert list(tmp_path.iterdir()) == []


def test_a_fixed_path_keeps_the_last_episode(tmp_path: Path) -> None:
    """A path without ``{seed}``/``{episode}`` is overwritten by each episode: documented, and a
    warning the first time it happens."""
    assert "overwritten by each episode" in (RecordEpisode.__doc__ or "")
    env = RecordEpisode(_env(), tmp_path / "x.rrd")
    _fly(env, seed=1)
    with pytest.warns(UserWarning, match=r"replaces an earlier episode's recording"):
        _fly(env, seed=2)
    env.close()
    assert env.written == [tmp_path / "x.rrd"] * 2 and [p.name for p in tmp_path.iterdir()] == ["x.rrd"]


def test_a_failed_write_names_the_file(tmp_path: Path) -> None:
    """The file writer stopping (here a 4 kB file-size limit, as a full disk stops it) raises
    RecordingWriteError, an OSError naming the file; no temporary file is left."""
    out = tmp_path / "full.rrd"
    code = textwrap.dedent(
        f"""
        import resource, signal
        import gymnasium as gym
        import ihrcf_env
        from ihrcf_env.record import RecordEpisode, RecordingWriteError
        env = RecordEpisode(
            gym.make({LANDING_V2_ID!r}, camera_model="projected", max_episode_steps={STEPS}), {str(out)!r}
        )
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))
        env.reset(seed=0)
        try:
            while True:
                *_, term, trunc, info = env.step(env.action_space.sample() * 0)
                if term or trunc:
                    break
        except RecordingWriteError as e:
            assert isinstance(e, OSError)
            print("ERROR", e)
        env.close()
        """
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    assert f"ERROR writing the recording {str(out)!r} failed" in run.stdout, run.stdout
    assert list(tmp_path.iterdir()) == []
    assert issubclass(RecordingWriteError, OSError)
