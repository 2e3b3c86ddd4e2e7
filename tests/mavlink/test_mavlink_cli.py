"""``ihrcf-mavlink``: usage errors exit 2 naming the argument, Ctrl-C exits 130 with the sockets
closed, and the benchmark line."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys
import time

import pytest
from udp_helpers import free_udp_port

from ihrcf_env.cmdline.common import EXIT_INTERRUPTED
from ihrcf_env.mavlink import command as cli

pytestmark = pytest.mark.filterwarnings("ignore:.*DeckLanding-v1 is out of date")
FAST = ["--camera-model", "projected"]


def _usage_error(capsys: pytest.CaptureFixture[str], argv: list[str]) -> str:
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["--out", "tcp:127.0.0.1:5760"], "--out"),
        (["--out", "udpout:127.0.0.1:0"], "--out"),
        (["--out", "udpout:no-such-host.invalid:14540"], "--out"),
        (["--speed", "0"], "--speed"),
        (["--speed", "nan"], "--speed"),
        (["--episodes", "0"], "--episodes"),
        (["--target", "pnp"], "--target"),
        (["--profile", "inav"], "--profile"),
        (["--option", "action_mode=motors"], "action_mode"),
        (["--env-id", "ihrcf_env/DeckHoverRaw-v0"], "no estimators"),
        (["--bench", "-1"], "--bench"),
    ],
)
def test_usage_errors_exit_2_naming_the_argument(
    capsys: pytest.CaptureFixture[str], argv: list[str], named: str
) -> None:
    assert named in _usage_error(capsys, [*FAST, *argv])


def test_a_port_in_use_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", port))
        err = _usage_error(capsys, [*FAST, "--out", f"udpin:127.0.0.1:{port}"])
    assert "--out" in err and "in use" in err


def test_a_destination_the_machine_will_not_send_to_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    """The broadcast address without the broadcast option: the first send fails, at start."""
    err = _usage_error(capsys, [*FAST, "--out", "udpout:255.255.255.255:14550"])
    assert "--out" in err and "cannot send" in err


def test_ctrl_c_exits_130_with_the_sockets_closed() -> None:
    port = free_udp_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "ihrcf_env.mavlink", *FAST, "--out", f"udpin:127.0.0.1:{port}"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # the vehicle is up
        assert "waiting for arming" in first or "ihrcf-mavlink" in first, first
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == EXIT_INTERRUPTED, err[-2000:]
    assert "Traceback" not in err and err.rstrip().endswith("ihrcf-mavlink: interrupted")
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:  # the port is free again
        again.bind(("127.0.0.1", port))


def test_bench_prints_the_real_time_factor_and_the_rates(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    assert cli.main([*FAST, "--out", f"udpout:127.0.0.1:{port}", "--bench", "2"]) == 0
    out = capsys.readouterr().out
    rtf = re.search(r"real-time factor ([0-9.]+)x \(2\.0 s simulated", out)
    assert rtf is not None and float(rtf.group(1)) > 0, out
    rates = dict(re.findall(r"^\s+([A-Z_]+)\s+\d+\s+([0-9.]+) Hz simulated", out, re.M))
    assert float(rates["LOCAL_POSITION_NED"]) == pytest.approx(20.0, rel=0.05)  # the control rate
    assert float(rates["DISTANCE_SENSOR"]) == pytest.approx(80.0, rel=0.05)  # 4 beams
    assert float(rates["EXTENDED_SYS_STATE"]) == pytest.approx(5.0, rel=0.2)
    assert 0 < float(rates["LANDING_TARGET"]) <= 20.0
