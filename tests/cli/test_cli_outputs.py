"""calibrate and fit_detector check their outputs and seeds before the long run, write whole, and
never touch the package's installed data."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import ihrcf_env
import ihrcf_env.experiments.detector_fit as detector_fit
import ihrcf_env.sim.calibration_procedure as calibration_procedure
from ihrcf_env.cli.calibrate import main as calibrate
from ihrcf_env.cli.fit_detector import DEFAULT_OUTPUT, build_parser
from ihrcf_env.cli.fit_detector import main as fit_detector
from ihrcf_env.cmdline.common import write_whole
from ihrcf_env.core.detector_model import DetectorModel, default_detector_model_path


@pytest.fixture
def no_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """The calibration and the detector fit fail the test if they start."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the long run started before the arguments were checked")

    monkeypatch.setattr(calibration_procedure, "run_calibration", refuse)
    monkeypatch.setattr(detector_fit, "fit_detector_model", refuse)


def _refused(capsys: pytest.CaptureFixture[str], main, argv: list[str]) -> str:  # type: ignore[no-untyped-def]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.usefixtures("no_run")
@pytest.mark.parametrize("command", ["calibrate", "fit_detector"])
def test_a_folder_as_output_is_refused_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    main, option = (calibrate, "--output") if command == "calibrate" else (fit_detector, "--out")
    err = _refused(capsys, main, [option, str(tmp_path)])
    assert option in err and "folder" in err
    assert list(tmp_path.iterdir()) == []  # no stray temporary file


@pytest.mark.usefixtures("no_run")
@pytest.mark.parametrize("command", ["calibrate", "fit_detector"])
def test_a_negative_seed_is_refused(capsys: pytest.CaptureFixture[str], command: str) -> None:
    main = calibrate if command == "calibrate" else fit_detector
    assert "--seed" in _refused(capsys, main, ["--seed", "-1"])


@pytest.mark.usefixtures("no_run")
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc")
@pytest.mark.parametrize("command", ["calibrate", "fit_detector"])
def test_an_unwritable_folder_is_refused(capsys: pytest.CaptureFixture[str], command: str) -> None:
    main, option = (calibrate, "--output") if command == "calibrate" else (fit_detector, "--out")
    err = _refused(capsys, main, [option, "/proc/x.json"])
    assert option in err and "/proc" in err


@pytest.mark.usefixtures("no_run")
@pytest.mark.parametrize("command", ["calibrate", "fit_detector"])
def test_a_special_file_as_output_is_refused_and_left_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """A FIFO made here stands for any special file (a device node alike): refused before the run,
    never replaced by the written file."""
    main, option = (calibrate, "--output") if command == "calibrate" else (fit_detector, "--out")
    fifo = tmp_path / "out.json"
    os.mkfifo(fifo)
    err = _refused(capsys, main, [option, str(fifo)])
    assert option in err and "not a regular file" in err
    assert fifo.is_fifo()
    with pytest.raises(FileExistsError, match="not a regular file"):
        write_whole(fifo, "{}\n")
    assert fifo.is_fifo() and [p.name for p in tmp_path.iterdir()] == ["out.json"]


@pytest.mark.usefixtures("no_run")
def test_an_output_under_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "file").write_text("x")
    err = _refused(capsys, calibrate, ["--output", str(tmp_path / "file" / "cal.json")])
    assert "--output" in err and "not a folder" in err


def test_write_whole_leaves_no_temporary_file(tmp_path: Path) -> None:
    target = tmp_path / "out.json"
    assert write_whole(target, "{}\n") == target and target.read_text() == "{}\n"
    (tmp_path / "taken").mkdir()
    with pytest.raises(OSError):
        write_whole(tmp_path / "taken", "{}\n")  # a folder appeared after the check
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.json", "taken"]
    assert list((tmp_path / "taken").iterdir()) == []


def test_fit_detector_writes_to_the_working_directory_not_the_package(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    shipped = default_detector_model_path()
    package = Path(ihrcf_env.__file__).resolve().parent
    assert DEFAULT_OUTPUT == build_parser().parse_args([]).out == "detector_model.json"
    before = (shipped.stat().st_mtime_ns, shipped.read_bytes())
    model = DetectorModel.load(shipped)
    seen: list[tuple[int, int]] = []

    def fake_fit(frames: int, seed: int, progress: object, samples: object) -> DetectorModel:
        seen.append((frames, seed))
        return model

    monkeypatch.setattr(detector_fit, "fit_detector_model", fake_fit)
    monkeypatch.chdir(tmp_path)
    assert fit_detector(["--frames", "12", "--seed", "5", "--quiet"]) == 0
    assert seen == [(12, 5)]
    written = tmp_path / "detector_model.json"
    assert DetectorModel.load(written).params("ideal") == model.params("ideal")
    assert not written.resolve().is_relative_to(package)
    assert (shipped.stat().st_mtime_ns, shipped.read_bytes()) == before
    assert "wrote detector_model.json" in capsys.readouterr().out
    assert sorted(os.listdir(tmp_path)) == ["detector_model.json"]
