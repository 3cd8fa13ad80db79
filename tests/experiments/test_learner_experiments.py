"""The learner benchmarks' suites as experiment files (experiments/learner-*.toml): each expands to the
runs studies/learner-benchmarks/learning.py's suite ran (checked equal once against its configs: the
same run names and settings, the demonstrations' on or off), here written out."""

from __future__ import annotations

from pathlib import Path

import pytest

from tsrl.experiments.config import load_experiment

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
REACH, PANDA = "tsrl/UR5eReach-v0", "tsrl/PandaReach-v0"
#: name -> (envs, obs, seeds, (budget, eval every, eval episodes), agents as (learner, HER relabel, demos)).
SUITES = {
    "learner-her": ((REACH,), "fs1", 3, (6_000, 200, 20), [("paper", "feature", False), ("paper", "plain", False)]),
    "learner-panda": ((PANDA, REACH), "fs1", 3, (6_000, 200, 20), [("paper", "feature", False)]),
    "learner-demos": (("tsrl/UR5ePickPlace-v0",), "fs1", 5, (50_000, 2_500, 100), [("paper", "feature", True), ("paper", "feature", False)]),
    "learner-fast-reach": ((REACH,), "fs1", 5, (3_000, 100, 20), [("fast", "feature", False), ("paper", "feature", False)]),
    "learner-fast-obstacle": (("tsrl/UR5eObstacleReach-v1",), "fs1", 5, (8_000, 500, 50), [("fast", "feature", False), ("paper", "feature", False)]),
    "learner-fast-pose": (("tsrl/UR5ePoseReach-v0",), "fs2", 5, (25_000, 2_500, 50), [("fast", "feature", False), ("paper", "feature", False)]),
}  # fmt: skip


@pytest.mark.parametrize("name", SUITES)
def test_a_suites_file_expands_to_its_runs(name: str) -> None:
    envs, obs, seeds, budget, agents = SUITES[name]
    runs = load_experiment(EXPERIMENTS / f"{name}.toml").runs()
    got = [
        (c.env_id, c.obs, c.seed, (c.total_timesteps, c.eval_freq, c.eval_episodes))
        + (c.agent.learner, c.agent.her.relabel, c.agent.demos.active)
        for c in runs
    ]
    expected = [(env, obs, seed, budget, *agent) for seed in range(seeds) for env in envs for agent in agents]
    assert got == expected
    assert len({c.run_name for c in runs}) == len(runs)
    assert {c.agent.algo for c in runs if c.agent.learner == "paper"} <= {"ddpg"}
