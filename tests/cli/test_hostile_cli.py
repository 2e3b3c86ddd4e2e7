"""What a hostile user gives the command lines: each is a usage error (exit status 2, one message
naming the argument, no traceback) before any long run, Ctrl-C ends a command with a short
message, and the files written get the mode a plain ``open`` gives."""

from __future__ import annotations

import importlib
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import corrupt_policy_files

import ihrcf_env
import ihrcf_env.cli.benchmark as benchmark_cli
import ihrcf_env.cli.evaluate as evaluate_cli
import ihrcf_env.sim.calibration_procedure as calibration_procedure
from ihrcf_env.cli import COMMANDS
from ihrcf_env.cmdline.common import EXIT_INTERRUPTED, write_whole
from ihrcf_env.cmdline.episode_args import check_episode_args
from ihrcf_env.experiments.policies import PolicyError, make_policy


def _usage_error(capsys: pytest.CaptureFixture[str], main: Callable[..., int], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "allow_pickle" not in err, err
    assert len([line for line in err.splitlines() if "error:" in line]) == 1, err
    return err


@pytest.fixture
def no_env(monkeypatch: pytest.MonkeyPatch) -> None:
    """Building an env fails the test: the arguments must be refused first."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("an env was built before the arguments were checked")

    monkeypatch.setattr(evaluate_cli.gym, "make", refuse)


@pytest.fixture
def no_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """The calibration and the benchmark's timings fail the test if they start."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the long run started before the arguments were checked")

    monkeypatch.setattr(calibration_procedure, "run_calibration", refuse)
    for name in ("raw_speed", "mode_speeds", "accuracy", "vector_speed", "single_speed"):
        monkeypatch.setattr(benchmark_cli, name, refuse)


# -- ihrcf-evaluate ----------------------------------------------------------------------------
@pytest.mark.usefixtures("no_env")
@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--policy", "scripted", "--option", "action_mode=motors"], ("action_mode", "velocity")),
        (["--policy", "blind:0.3", "--option", "action_mode=motors"], ("action_mode", "velocity")),
        (["--policy", "scripted", "--option", "render_mode=human"], ("render_mode",)),
        (["--policy", "blind:0.3", "--option", "render_mode=rgb_array"], ("render_mode",)),
        (["--policy", "scripted", "--option", 'estimators=["ihrcf"]'], ("estimators", "fused")),
        (["--policy", "scripted", "--option", "estimators=ihrcf"], ("estimators", "fused")),
        (["--policy", "blind:0.3", "--option", "wind=" + "[" * 100_000 + "]" * 100_000], ("wind", "nested")),
    ],
)
def test_evaluate_refuses_options_the_policy_cannot_fly(
    capsys: pytest.CaptureFixture[str], argv: list[str], words: tuple[str, ...]
) -> None:
    err = _usage_error(capsys, evaluate_cli.main, argv)
    assert "--option" in err and all(w in err for w in words), err


def test_evaluate_keeps_options_the_policy_flies(monkeypatch: pytest.MonkeyPatch) -> None:
    """The option checks refuse only what the policy cannot fly: the fused estimator with others,
    velocity actions said explicitly."""
    seen: list[dict[str, Any]] = []

    def stop(env_id: str, **kwargs: Any) -> None:
        seen.append(kwargs)
        raise KeyboardInterrupt  # stops the command here, once the arguments passed

    monkeypatch.setattr(evaluate_cli.gym, "make", stop)
    argv = [
        "--policy",
        "scripted",
        "--option",
        'estimators=["ihrcf", "fused"]',
        "--option",
        "action_mode=velocity",
    ]
    assert evaluate_cli.main(argv) == EXIT_INTERRUPTED
    assert seen == [{"estimators": ["ihrcf", "fused"], "action_mode": "velocity"}]


def test_make_policy_reads_the_env_action_mode_and_estimators(make_env: Any) -> None:
    """The guard of the policies themselves, on built envs: a motors env and an env without the
    fused estimate are refused with PolicyError (the CLI's usage error), not flown."""
    motors = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", action_mode="motors")
    for spec in ("scripted", "blind:0.3"):
        with pytest.raises(PolicyError, match="action_mode='motors'"):
            make_policy(spec, motors)
    ihrcf_only = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected", estimators=("ihrcf",))
    with pytest.raises(PolicyError, match="fused"):
        make_policy("scripted", ihrcf_only)
    velocity = make_env(ihrcf_env.LANDING_V2_ID, camera_model="projected")
    assert make_policy("scripted", velocity) is not None


@pytest.mark.usefixtures("no_env")
def test_evaluate_names_a_corrupt_policy_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for kind, (path, word) in corrupt_policy_files(tmp_path).items():
        err = _usage_error(capsys, evaluate_cli.main, ["--policy", str(path)])
        assert "--policy" in err and path.name in err and word in err, (kind, err)


# -- ihrcf-calibrate, ihrcf-benchmark ----------------------------------------------------------
@pytest.mark.usefixtures("no_run")
@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--width", "1000000000"], "--width"),
        (["--height", "1000000000"], "--height"),
        (["--width", "8"], "--width"),
        (["--stages", str(10**9)], "--stages"),
        (["--views", str(10**9)], "--views"),
        (["--top", "1e300"], "--top"),
        (["--top", "nan"], "--top"),
        (["--bottom", "inf"], "--bottom"),
        (["--bottom", "0"], "--bottom"),
        (["--output", ""], "--output"),
        (["--output", "  "], "--output"),
    ],
)
def test_calibrate_refuses_absurd_arguments(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    option: str,
) -> None:
    from ihrcf_env.cli.calibrate import main

    monkeypatch.chdir(tmp_path)
    assert option in _usage_error(capsys, main, argv)
    assert list(tmp_path.iterdir()) == []  # no default-named file written instead


@pytest.mark.usefixtures("no_run")
@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["--sizes", "8"], "--sizes"),
        (["--sizes", "0", "128", "15"], "--sizes"),
        (["--sizes", "1000000000"], "--sizes"),
        (["--no-speed", "--no-accuracy"], "--no-speed"),
    ],
)
def test_benchmark_refuses_before_the_tables(
    capsys: pytest.CaptureFixture[str], argv: list[str], option: str
) -> None:
    assert option in _usage_error(capsys, benchmark_cli.main, argv)


# -- every command ----------------------------------------------------------------------------
@pytest.mark.parametrize("module", sorted(COMMANDS.values()))
def test_ctrl_c_ends_a_command_with_a_message_and_status_130(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], module: str
) -> None:
    cli = importlib.import_module(module)

    def interrupted() -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main([]) == EXIT_INTERRUPTED
    err = capsys.readouterr().err
    assert "interrupted" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


@pytest.fixture
def umask() -> Iterator[Callable[[int], None]]:
    """``umask(mask)`` sets the process's umask for the test; the old one comes back after."""
    old = os.umask(0o022)
    os.umask(old)
    yield lambda mask: os.umask(mask) and None
    os.umask(old)


@pytest.mark.parametrize("mask", [0o022, 0o002, 0o077, 0o027])
def test_written_files_get_the_mode_of_a_plain_open(
    tmp_path: Path, umask: Callable[[int], None], mask: int
) -> None:
    umask(mask)
    plain = tmp_path / "plain.txt"
    with open(plain, "w") as f:
        f.write("x")
    written = write_whole(tmp_path / "sub" / "written.json", "{}\n")
    assert stat.S_IMODE(written.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode) == 0o666 & ~mask


def test_an_existing_file_keeps_its_mode(tmp_path: Path, umask: Callable[[int], None]) -> None:
    umask(0o077)
    target = tmp_path / "shared.json"
    target.write_text("old\n")
    target.chmod(0o644)
    write_whole(target, "new\n")
    assert target.read_text() == "new\n" and stat.S_IMODE(target.stat().st_mode) == 0o644


def test_a_command_writes_its_file_with_the_mode_of_a_plain_open(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, umask: Callable[[int], None]
) -> None:
    import ihrcf_env.experiments.detector_fit as detector_fit
    from ihrcf_env.cli.fit_detector import main as fit_detector
    from ihrcf_env.core.detector_model import DetectorModel

    model = DetectorModel.load()
    monkeypatch.setattr(detector_fit, "fit_detector_model", lambda *args, **kwargs: model)
    umask(0o022)
    out = tmp_path / "model.json"
    assert fit_detector(["--frames", "12", "--quiet", "--out", str(out)]) == 0
    assert stat.S_IMODE(out.stat().st_mode) == 0o644


def test_ctrl_c_in_a_running_command(tmp_path: Path) -> None:
    """SIGINT while the calibration runs: a one-line message, exit status 130, no traceback."""
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "ihrcf_env.calibrate", "--output", str(tmp_path / "cal.json")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stderr is not None
        first = ""
        while "chessboard:" not in first:  # the calibration's own progress: main is running
            char = proc.stderr.read(1)
            assert char, f"the calibration ended before its progress: {first!r}"
            first += char
        proc.send_signal(signal.SIGINT)
        _, rest = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    err = first + rest
    assert proc.returncode == EXIT_INTERRUPTED, err[-2000:]
    assert "Traceback" not in err and err.rstrip().endswith("ihrcf-calibrate: interrupted")
    assert not (tmp_path / "cal.json").exists()


#: A Ctrl-C that lands while the command module is being imported: an audit hook sends SIGINT to
#: the process when Python opens the code of ``ihrcf_env/cli/<module>.py`` to import it (the
#: KeyboardInterrupt is raised at the next instruction, inside that import).
_STARTUP_CTRL_C = """
import os, signal, sys
target = os.path.join(*sys.argv[1].split("."))
def hook(event, args):
    if event == "open" and isinstance(args[0], str) and target in args[0].replace("__pycache__" + os.sep, ""):
        os.kill(os.getpid(), signal.SIGINT)
sys.addaudithook(hook)
sys.argv = ["ihrcf-" + sys.argv[2], "--help"]
"""


@pytest.mark.parametrize(("name", "module"), sorted(COMMANDS.items()))
def test_ctrl_c_during_start_up_exits_130_without_a_traceback(name: str, module: str) -> None:
    """The console script's entry point (as pip writes it: ``from X import f; sys.exit(f())``) and
    the ``python -m`` launcher: a Ctrl-C while the command is still being imported ends it with the
    one-line message and status 130."""
    import subprocess
    import sys
    import tomllib

    root = Path(__file__).resolve().parents[2]
    target = tomllib.loads((root / "pyproject.toml").read_text())["project"]["scripts"][f"ihrcf-{name}"]
    where, _, func = target.partition(":")
    launcher = f"ihrcf_env.{name.replace('-', '_')}"  # a module at the root, or a package's __main__
    for tail in (
        f"from {where} import {func}\nsys.exit({func}())",
        f"import runpy\nrunpy.run_module({launcher!r}, run_name='__main__', alter_sys=True)",
    ):
        run = subprocess.run(
            [sys.executable, "-c", _STARTUP_CTRL_C + tail, module, name],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert run.returncode == EXIT_INTERRUPTED, (tail, run.stderr[-2000:])
        assert "Traceback" not in run.stderr and run.stderr.rstrip().endswith(f"ihrcf-{name}: interrupted")
        assert "usage:" not in run.stdout  # stopped before main parsed anything


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (
            ["--option", "camera_model=rendered", "--camera-model", "projected"],
            ("camera_model", "--camera-model"),
        ),
        (["--level", "calm", "--option", "level=rough"], ("level", "--level")),
        (["--max-steps", "5", "--option", "max_episode_steps=9"], ("max_episode_steps", "--max-steps")),
        (
            ["--sensor-preset", "ideal", "--option", "sensor_preset=realistic"],
            ("sensor_preset", "--sensor-preset"),
        ),
        (["--deck-motion", "--option", "deck_motion=false"], ("deck_motion", "--deck-motion")),
    ],
)
@pytest.mark.usefixtures("no_env")
def test_an_option_and_its_flag_with_two_values_are_a_usage_error(
    capsys: pytest.CaptureFixture[str], argv: list[str], names: tuple[str, str]
) -> None:
    from ihrcf_env.record.command import main as record

    for main, extra in ((evaluate_cli.main, []), (record, ["--out", "never.rrd"])):
        err = _usage_error(capsys, main, ["--policy", "blind:0.3", *argv, *extra])
        assert all(n in err for n in names), err


def test_an_option_and_its_flag_with_one_value_pass(monkeypatch: pytest.MonkeyPatch) -> None:
    """The same value given twice is no conflict."""
    import argparse

    ap = evaluate_cli.build_parser()
    args = ap.parse_args(
        ["--policy", "blind:0.3", "--camera-model", "projected", "--option", "camera_model=projected"]
    )
    check_episode_args(ap, args)
    assert args.options == {"camera_model": "projected"} and isinstance(args, argparse.Namespace)
