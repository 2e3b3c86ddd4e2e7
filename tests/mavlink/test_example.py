"""examples/mavsdk_landing.py lands on the calm level through the MAVLink vehicle: the vehicle and
the example as two processes on localhost UDP, at 4x real time, the level's test seeds."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
from conftest import EXAMPLES
from udp_helpers import free_udp_port

pytest.importorskip("mavsdk")


def _fly(landings: int, speed: float = 4.0) -> tuple[int, str, str]:
    """Successes counted by the vehicle, its output and the example's."""
    port, targets = free_udp_port(), free_udp_port()
    vehicle = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "ihrcf_env.mavlink",
            "--level",
            "calm",
            "--camera-model",
            "projected",
            "--speed",
            str(speed),
            "--episodes",
            str(landings),
            "--out",
            f"udpout:127.0.0.1:{port}",
            "--out",
            f"udpout:127.0.0.1:{targets}",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        example = subprocess.run(
            [
                sys.executable,
                str(EXAMPLES / "mavsdk_landing.py"),
                "--connect",
                f"udpin://127.0.0.1:{port}",
                "--targets",
                f"udpin:127.0.0.1:{targets}",
                "--landings",
                str(landings),
            ],
            capture_output=True,
            text=True,
            timeout=60 + 30 * landings,
            check=False,
        )
        out, _ = vehicle.communicate(timeout=60)
    finally:
        if vehicle.poll() is None:
            vehicle.kill()
            vehicle.wait()
    assert vehicle.returncode == 0, out
    assert example.returncode == 0, example.stdout + example.stderr
    match = re.search(r"^episodes (\d+), success (\d+)/(\d+)$", out, re.M)
    assert match is not None, out
    assert int(match.group(1)) == landings
    reports = re.findall(r"^touchdown \d+: (.*)$", example.stdout, re.M)
    assert len(reports) == landings, example.stdout
    assert sum("success" in r for r in reports) == int(match.group(2))  # the example saw what happened
    return int(match.group(2)), out, example.stdout


def test_the_example_lands_twice_on_calm() -> None:
    ok, out, _ = _fly(2)
    assert ok == 2, out


@pytest.mark.slow
def test_the_example_lands_on_calm_in_at_least_9_of_10_seeds() -> None:
    ok, out, _ = _fly(10)
    assert ok >= 9, out
