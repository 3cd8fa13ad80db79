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


HALF_STEP = ROOT / "benchmarks" / "task_files" / "panda_push_half_step.toml"


def test_a_task_file_runs_as_the_family_task_its_solver_names(tmp_path: Path) -> None:
    from tsrl.envs import load_task

    task = str(HALF_STEP)
    assert (
        family.family_task(task) == "PandaPush-v0" and family.family_task("PandaStack-v0") == "PandaStack-v0"
    )
    half, push = load_task(task), load_task("PandaPush-v0")
    assert half.action_spec.parts[0].step == push.action_spec.parts[0].step / 2  # the one change it makes
    assert half.observation == push.observation and half.goal == push.goal
    cfgs = family.configs(task, [0, 1], 30_000, 2_500, tmp_path / "demos.npz", "fast")
    assert {c.env_id for c in cfgs} == {family.env_id(task)} == {str(HALF_STEP.resolve())}
    assert family.run_parent(task, 100, None) == "panda_push_half_step"
    assert learning_tables.family_label(cfgs[0].env_id) == "panda_push_half_step.toml"
    assert learning_tables.family_label("tsrl/PandaPush-v0") == "tsrl/PandaPush-v0"


TASK_FILES = ROOT / "benchmarks" / "task_files"


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
    from tsrl.envs import load_task

    task = str(TASK_FILES / file)
    assert family.family_task(task) == task_id
    half, full = load_task(task), load_task(task_id)
    assert half.action_spec.parts[0].step == full.action_spec.parts[0].step / 2  # the one change it makes
    assert half.action_spec.gripper and not half.action_spec.gripper_open_close
    assert half.observation == full.observation and half.goal == full.goal and half.success == full.success
    assert half.episode_steps == full.episode_steps == episode_steps
    demos = record_demos(task, 10, obs=half.observation, seed=0, keep_failed=True)
    assert demos.is_success[:, -1].sum() >= 9  # 99-100 of 100 seeded episodes within the episode's steps


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("PandaReach-v0", "--tasks: 'PandaReach-v0' is not a family task; accepted: PandaPush-v0"),
        ("reach.toml", "solver = 'PandaReach-v0'; a family variant needs the family task it varies"),
    ],
)
def test_tasks_outside_the_family_are_refused(
    entry: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = HALF_STEP.read_text().replace('solver = "PandaPush-v0"', 'solver = "PandaReach-v0"')
    (tmp_path / "reach.toml").write_text(text)
    task = str(tmp_path / entry) if entry.endswith(".toml") else entry
    with pytest.raises(SystemExit) as exit_info:
        family.main(["--tasks", task])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_a_run_past_its_target_is_judged_against_the_target_and_names_its_budget(tmp_path: Path) -> None:
    """The gripper's 150,000-step runs (docs/results/benchmarks/family-gripper-150k): seed 0 reaches 95 %
    at 132,500, past the task's 60,000, so the table says the target and "no", not the runs' budget."""
    saved = ROOT / "docs" / "results" / "benchmarks" / "family-gripper-150k"
    (row,) = learning_tables.table_family(saved)[2:]
    assert row.startswith("| `tsrl/PandaPickPlaceGripper-v0` (learner fast, budget 150,000) | 60,000 |")
    assert "| 132,500, never |" in row and row.endswith("| no |")
    demos = tmp_path / "PandaPush-v0-scripted-100.npz"
    (at_target,) = family.configs("PandaPush-v0", [0], 30_000, 2_500, demos, "fast")
    (past,) = family.configs("PandaPush-v0", [0], 45_000, 2_500, demos, "fast")
    assert learning_tables.family_variant(at_target.to_dict()) == ["learner fast"]
    assert learning_tables.family_variant(past.to_dict()) == ["learner fast", "budget 45,000"]


def test_a_run_of_another_task_has_no_family_target() -> None:
    assert learning_tables.family_target("tsrl/PandaPickPlace-v0") is None
    assert learning_tables.family_target("/elsewhere/my_task.toml") is None
    assert learning_tables.family_target(str(HALF_STEP)) == 30_000


def test_utd_reaches_every_run_gets_its_own_folder_and_names_its_variant(tmp_path: Path) -> None:
    demos = tmp_path / "PandaPickPlaceGripper-v0-scripted-100.npz"
    more = family.configs("PandaPickPlaceGripper-v0", [0, 1], 60_000, 2_500, demos, "fast", utd=4.0)
    preset = family.configs("PandaPickPlaceGripper-v0", [0, 1], 60_000, 2_500, demos, "fast")
    assert [c.agent.utd for c in more] == [4.0, 4.0] and [c.agent.utd for c in preset] == [2.0, 2.0]
    assert learning_tables.family_variant(more[0].to_dict()) == ["learner fast", "UTD 4"]
    assert learning_tables.family_variant(preset[0].to_dict()) == ["learner fast"]
    # the run names are the same, so the variants' runs live in different folders and are never reused
    assert family.run_parent("PandaPickPlaceGripper-v0", 100, None, 4.0) == "PandaPickPlaceGripper-v0-utd-4"
    assert family.run_parent("PandaPickPlaceGripper-v0", 100, None) == "PandaPickPlaceGripper-v0"


@pytest.mark.parametrize("utd", ["0", "-1", "nan"])
def test_a_bad_utd_is_refused(utd: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        family.main(["--utd", utd])
    assert exit_info.value.code == 2
    assert f"--utd must be a finite number > 0 (gradient steps per env step); got {float(utd)}" in (
        capsys.readouterr().err
    )
