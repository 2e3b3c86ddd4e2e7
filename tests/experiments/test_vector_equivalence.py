"""``python -m ihrcf_env.experiments.vector_equivalence``: a few scripted landings in the vector env
against single envs, and the comparison's arithmetic on made-up episodes."""

from __future__ import annotations

import numpy as np
import pytest

import ihrcf_env
from ihrcf_env.experiments.vector_equivalence import Episode, compare, main, markdown


def _episode(values: list[float], outcome: str = "success") -> Episode:
    return Episode(np.array([[v, 0.0] for v in values], dtype=np.float32), outcome)


def test_compare_counts_agreement_and_the_largest_difference() -> None:
    vector = [_episode([0.0, 1.0, 2.0]), _episode([0.0, 1.0]), _episode([0.0, 1.0], "crash")]
    single = [_episode([0.0, 1.0, 2.0]), _episode([0.0, 1.0 + 2**-20]), _episode([0.0, 1.5, 3.0])]
    c = compare(vector, single)
    assert (c.episodes, c.same_outcome, c.same_length, c.bitwise, c.within_1e6) == (3, 2, 2, 1, 2)
    assert c.max_difference == 0.5  # over the common steps of the third
    assert c.outcomes == {"success": 2, "crash": 1}
    row = markdown([("x", c)])[2]
    assert row == "| x | 2/3 | 2/3 | 1/3 | 2/3 | 0.5 | crash 1, success 2 |"


def test_a_few_scripted_landings_agree_step_for_step(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--id", ihrcf_env.LANDING_V2_ID, "--episodes", "2"]
    assert main(argv) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.startswith("| the same options")]
    assert len(lines) == 1
    # each sub-env runs its own estimators, as the single env: equal bit for bit
    assert lines[0].startswith("| the same options | 2/2 | 2/2 | 2/2 | 2/2 | 0 |")


@pytest.mark.parametrize(
    ("argv", "name"),
    [(["--episodes", "0"], "--episodes"), (["--seed", "-1"], "--seed"), (["--level", "storm"], "--level")],
)
def test_bad_arguments_are_refused_by_name(
    argv: list[str], name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert f"argument {name}" in capsys.readouterr().err
