"""studies/manipulation-family/family_tables.py: how the family's tables name a run's variant, judge it
against its task's target (the budgets of experiments/manipulation-family.toml) and treat task files."""

from __future__ import annotations

from pathlib import Path

import pytest
from benchmark_modules import load_script, load_study

from tsrl.agents.config import TASK_ACTION, AgentConfig, DemoConfig, TrainConfig
from tsrl.envs import load_task
from tsrl.experiments.config import load_experiment

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "manipulation-family"
TASK_FILES = STUDY / "task_files"
HALF_STEP = TASK_FILES / "panda_push_half_step.toml"

tables = load_study("manipulation-family", "family_tables")


def family_run(task: str = "PandaPush-v0", total: int = 30_000, **agent: object) -> TrainConfig:
    """A family run as experiments/manipulation-family.toml (or a variant) makes it; DDPG unless `agent`
    says otherwise (the fast preset's own is TD3)."""
    env = task if task.endswith(".toml") else f"tsrl/{task}"
    demos = DemoConfig(path=f"demos/{Path(task).stem}-scripted-100.npz")
    return TrainConfig(
        env_id=env,
        obs=load_task(task).observation,
        action=TASK_ACTION,
        agent=AgentConfig(demos=demos, **({"algo": "ddpg"} | agent)),  # type: ignore[arg-type]
        total_timesteps=total,
        eval_freq=2_500,
        eval_episodes=100,
    )


def test_the_targets_are_the_experiment_files_budgets() -> None:
    exp = load_experiment(ROOT / "experiments" / "manipulation-family.toml")
    budgets = {b.env.removeprefix("tsrl/"): (b.total_timesteps, b.eval_freq) for b in exp.budgets}
    assert budgets == tables.FAMILY_TASKS


def test_the_variant_names_the_algorithm_the_learner_and_the_utd() -> None:
    assert tables.family_variant(family_run(algo="tqc", learner="fast").to_dict()) == ["TQC", "learner fast"]
    assert tables.family_variant(family_run(learner="fast").to_dict()) == ["learner fast"]
    assert tables.family_variant(family_run(learner="fast", utd=4.0).to_dict()) == ["learner fast", "UTD 4"]
    assert tables.family_variant(family_run().to_dict()) == []


def test_a_task_file_is_named_by_its_file_and_judged_by_the_family_task_its_solver_names() -> None:
    half, push = load_task(str(HALF_STEP)), load_task("PandaPush-v0")
    assert half.solver == "PandaPush-v0"
    assert half.action_spec.parts[0].step == push.action_spec.parts[0].step / 2  # the one change it makes
    assert half.observation == push.observation and half.goal == push.goal
    cfg = family_run(str(HALF_STEP))
    assert tables.family_label(cfg.env_id) == "panda_push_half_step.toml"
    assert tables.family_label("tsrl/PandaPush-v0") == "tsrl/PandaPush-v0"
    assert tables.family_target(cfg.env_id) == 30_000
    assert tables.compared_task(cfg.env_id) == ("tsrl/PandaPush-v0", ["panda_push_half_step.toml"])


@pytest.mark.parametrize(
    ("file", "task_id", "episode_steps"),
    [
        ("panda_pick_place_gripper_half_step.toml", "PandaPickPlaceGripper-v0", 50),
        ("panda_peg_insert_half_step.toml", "PandaPegInsert-v0", 75),
        ("panda_stack_half_step.toml", "PandaStack-v0", 100),
    ],
)
def test_a_gripper_half_step_halves_the_tcp_step_and_its_solver_still_succeeds(
    file: str, task_id: str, episode_steps: int
) -> None:
    from tsrl.agents.demonstrators import record_demos

    task = str(TASK_FILES / file)
    half, full = load_task(task), load_task(task_id)
    assert half.solver == task_id
    assert half.action_spec.parts[0].step == full.action_spec.parts[0].step / 2  # the one change it makes
    assert half.action_spec.gripper and not half.action_spec.gripper_open_close
    assert half.observation == full.observation and half.goal == full.goal and half.success == full.success
    assert half.episode_steps == full.episode_steps == episode_steps
    demos = record_demos(task, 10, obs=half.observation, seed=0, keep_failed=True)
    assert demos.is_success[:, -1].sum() >= 9  # 99-100 of 100 seeded episodes within the episode's steps


def test_a_run_past_its_target_is_judged_against_the_target_and_names_its_budget() -> None:
    """The gripper's 150,000-step runs (studies/manipulation-family/data/family-gripper-150k): seed 0 reaches 95 %
    at 132,500, past the task's 60,000, so the table says the target and "no", not the runs' budget."""
    saved = STUDY / "data" / "family-gripper-150k"
    (row,) = tables.table_family(saved)[2:]
    assert row.startswith("| `tsrl/PandaPickPlaceGripper-v0` (learner fast, budget 150,000) | 60,000 |")
    assert "| 132,500, never |" in row and row.endswith("| no |")
    assert tables.family_variant(family_run(learner="fast").to_dict()) == ["learner fast"]
    past = family_run(total=45_000, learner="fast")
    assert tables.family_variant(past.to_dict()) == ["learner fast", "budget 45,000"]


def test_a_run_of_another_task_has_no_family_target() -> None:
    assert tables.family_target("tsrl/PandaPickPlace-v0") is None
    assert tables.family_target("/elsewhere/my_task.toml") is None
    with pytest.raises(SystemExit, match="no task file 'elsewhere.toml' in .*task_files; accepted"):
        tables.compared_task("/some/machine/elsewhere.toml")


def test_a_family_experiments_runs_saved_render_the_family_table(tmp_path: Path) -> None:
    """`tsrl experiment`'s runner on the family file cut to seconds, its folder saved as
    scripts/save_experiment.py saves it: the family table judges it against the push's target."""
    import dataclasses
    import io

    from tsrl.experiments.config import DemoRecipe, TaskBudget
    from tsrl.experiments.pool import run_experiment

    save = load_script("save_experiment")
    push = "tsrl/PandaPush-v0"
    exp = dataclasses.replace(
        load_experiment(ROOT / "experiments" / "manipulation-family.toml"),
        env=(push,),
        seeds=(0, 1),
        budgets=(TaskBudget(push, total_timesteps=100, eval_freq=50),),
        eval_episodes=2,
        demos=DemoRecipe(episodes=2),
    )
    run_experiment(exp, tmp_path / "results", workers=2, stream=io.StringIO())
    out = tmp_path / "data"
    assert save.copy_experiment(tmp_path / "results" / exp.name, out) == 2
    assert (out / exp.name / "experiment.json").is_file()
    (row,) = tables.table_family(out)[2:]
    assert row.startswith("| `tsrl/PandaPush-v0` (budget 100) | 30,000 | 0, 1 |") and row.endswith("| no |")
