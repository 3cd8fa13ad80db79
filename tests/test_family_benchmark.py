"""benchmarks/family.py: the runs it builds (algorithm, learner, penalty) and how its tables name them."""

from __future__ import annotations

from pathlib import Path

import pytest
from benchmark_modules import load_benchmark

ROOT = Path(__file__).resolve().parents[1]


family = load_benchmark("family")
learning_tables = load_benchmark("learning_tables")


def test_algo_reaches_every_run_and_names_its_variant(tmp_path: Path) -> None:
    demos = tmp_path / "PandaPush-v0-scripted-100.npz"
    tqc = family.configs("PandaPush-v0", [0, 1], 30_000, 2_500, demos, "fast", algo="tqc")
    ddpg = family.configs("PandaPush-v0", [0, 1], 30_000, 2_500, demos, "fast")
    assert [c.agent.algo for c in tqc] == ["tqc", "tqc"] and [c.agent.algo for c in ddpg] == ["ddpg"] * 2
    assert {c.agent.learner for c in tqc + ddpg} == {"fast"}
    assert not {c.run_name for c in tqc} & {c.run_name for c in ddpg}  # never reuses the other's run
    assert learning_tables.family_variant(tqc[0].to_dict()) == ["TQC", "learner fast"]
    assert learning_tables.family_variant(ddpg[0].to_dict()) == ["learner fast"]


def test_an_unknown_algo_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        family.main(["--algo", "ppo"])
    assert exit_info.value.code == 2
    assert "--algo: invalid choice: 'ppo'" in capsys.readouterr().err
