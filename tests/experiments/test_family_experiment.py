"""experiments/manipulation-family.toml: the manipulation family's benchmark as an experiment file; it
expands to the grid benchmarks/family.py ran (each task's target budget and evaluation period, its own
observation and action, the paper's agent with 100 demonstrations, 5 seeds), and `tsrl experiment`'s
runner runs it (here cut to one task, one seed and seconds of training)."""

from __future__ import annotations

import dataclasses
import io
from pathlib import Path

from tsrl.agents.config import TASK_ACTION, AgentConfig, DemoConfig, TrainConfig
from tsrl.envs import load_task
from tsrl.experiments.config import DemoRecipe, TaskBudget, load_experiment
from tsrl.experiments.pool import run_experiment

FAMILY = Path(__file__).resolve().parents[2] / "experiments" / "manipulation-family.toml"
#: The family's tasks: (target budget, evaluation every) [env steps], as benchmarks/family.py ran them.
TARGETS = {
    "PandaPush-v0": (30_000, 2_500),
    "PandaPickPlaceGripper-v0": (60_000, 2_500),
    "PandaStack-v0": (150_000, 10_000),
    "PandaPegInsert-v0": (150_000, 10_000),
}


def _without_demo_path(cfg: TrainConfig) -> dict[str, object]:
    d = cfg.to_dict()
    d["agent"]["demos"]["path"] = None
    return d


def test_the_file_expands_to_the_family_grid_seed_first() -> None:
    exp = load_experiment(FAMILY)
    runs = exp.runs()
    expected = [
        TrainConfig(
            env_id=f"tsrl/{task}",
            obs=load_task(task).observation,
            action=TASK_ACTION,
            seed=seed,
            agent=AgentConfig(demos=DemoConfig(path="demos.npz")),
            total_timesteps=target,
            eval_freq=eval_freq,
            eval_episodes=100,
        )
        for seed in range(5)
        for task, (target, eval_freq) in TARGETS.items()
    ]
    assert [_without_demo_path(c) for c in runs] == [_without_demo_path(c) for c in expected]
    assert exp.demos == DemoRecipe(episodes=100, seed=0)
    assert len({c.agent.demos.path for c in runs}) == len(TARGETS)  # one recording per task
    assert exp.arms() == [f"tsrl/{task}" for task in TARGETS]  # each task's own obs goes with its env


def test_the_runner_runs_the_file_cut_to_seconds(tmp_path: Path) -> None:
    push = "tsrl/PandaPush-v0"
    exp = dataclasses.replace(
        load_experiment(FAMILY),
        env=(push,),
        seeds=(0,),
        budgets=(TaskBudget(push, total_timesteps=100, eval_freq=50),),
        eval_episodes=2,
        demos=DemoRecipe(episodes=2),
    )
    (outcome,) = run_experiment(exp, tmp_path, workers=1, stream=io.StringIO())
    assert (outcome.status, outcome.env_steps) == ("trained", 100), outcome.error
    assert (tmp_path / "manipulation-family" / "demos").is_dir()
