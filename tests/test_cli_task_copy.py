"""Runs keep their task: `tsrl train --task FILE` trains the file's own observation and action (unless
--obs / --action are given), the run folder keeps copies of the task's files with their sha256s, and
`--resume` and `tsrl evaluate` use the copies, with one notice per changed original."""

from __future__ import annotations

import csv
import hashlib
import json
import shutil
import tomllib
from pathlib import Path

import gymnasium as gym
import pytest
from cli_runner import RUN_NAME, TINY, run_tsrl
from own_task import EPISODE_STEPS, OBSERVATION, write_task
from stable_baselines3.common.save_util import load_from_zip_file

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import TrainConfig
from tsrl.agents.run_folder import with_task_copy, write_task_record
from tsrl.agents.task_record import recorded_task
from tsrl.cli import parse
from tsrl.envs import TASK_ENV_ID
from tsrl.envs.tasks import builtin_task_path

REPO = Path(__file__).resolve().parents[1]


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def notices(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("tsrl: notice:")]


@pytest.fixture(scope="module")
def task_file(tmp_path_factory) -> Path:
    return write_task(tmp_path_factory.mktemp("my_task"))


@pytest.fixture(scope="module")
def trained(task_file, tmp_path_factory) -> Path:
    """A run trained through the CLI on the task file, neither --obs nor --action given."""
    out = tmp_path_factory.mktemp("runs")
    result = run_tsrl("train", "--task", str(task_file), "--out-dir", str(out), *TINY)
    assert result.returncode == 0, result.stderr
    assert not notices(result.stderr)
    (run_dir,) = out.iterdir()
    return run_dir


@pytest.fixture
def originals(task_file):
    """The task's files, put back as they were after the test (which may edit or delete them)."""
    saved = {p: p.read_bytes() for p in task_file.parent.iterdir()}
    yield task_file.parent
    for p, data in saved.items():
        p.write_bytes(data)


def break_originals(folder: Path) -> None:
    """Another episode length in the task file, a TCP the model lacks in the robot file, a model file
    MuJoCo cannot read: a run that read any of them would not be the run that was trained."""
    task = folder / "task.toml"
    task.write_text(task.read_text().replace(f"episode_steps = {EPISODE_STEPS}", "episode_steps = 10"))
    robot = folder / "arm.toml"
    robot.write_text(robot.read_text().replace('tcp = "tool"', 'tcp = "nope"'))
    (folder / "arm.xml").write_text("<mujoco><worldbody><body name='not the arm'/></mujoco>")


def test_a_task_file_trains_its_own_observation_and_action(trained, task_file):
    config = json.loads((trained / "config.json").read_text())
    assert config["env_id"] == str(task_file)
    assert config["obs"] == tomllib.loads(task_file.read_text())["observation"] == OBSERVATION
    assert config["action"] == "task"  # the file's [action] table
    spec = hashlib.sha1(OBSERVATION.encode()).hexdigest()[:8]
    assert trained.name == f"task-task__spec-{spec}__task__ddpg__s0"  # says what it trains: not __fs1__
    # The networks saw the task's own observation: the checkpoint's observation space is the task's.
    model = max(trained.glob("checkpoints/step_*/model.zip"))
    data, _, _ = load_from_zip_file(model)
    own = gym.make(TASK_ENV_ID, task=str(task_file), max_episode_steps=EPISODE_STEPS)
    fs1 = gym.make(TASK_ENV_ID, task=str(task_file), obs="fs1", max_episode_steps=EPISODE_STEPS)
    seen = data["observation_space"]["observation"].shape
    assert seen == own.observation_space["observation"].shape != fs1.observation_space["observation"].shape


@pytest.mark.parametrize(
    ("given", "obs", "action"),
    [
        ([], OBSERVATION, "task"),
        (["--obs", "fs1"], "fs1", "task"),
        (["--action", "joint"], OBSERVATION, "joint"),
        (["--obs", "fs0", "--action", "taskspace"], "fs0", "taskspace"),
        (["--learner", "fast"], OBSERVATION, "task"),  # parsed again over the preset's defaults
    ],
)
def test_obs_and_action_given_replace_the_files_own_and_the_name_says_so(given, obs, action, task_file):
    cfg = parse(["train", "--task", str(task_file), *given]).config
    assert (cfg.obs, cfg.action) == (obs, action)
    assert cfg.run_name.split("__")[2] == action
    assert (cfg.run_name.split("__")[1] == obs) == (obs != OBSERVATION)  # a spec is spec-<hash>


def test_a_files_action_mode_is_named_and_a_registered_environment_keeps_the_defaults():
    example = REPO / "examples" / "tasks" / "my_reach.toml"  # action = "taskspace", its own observation
    cfg = parse(["train", "--task", str(example)]).config
    assert (cfg.obs, cfg.action) == (tomllib.loads(example.read_text())["observation"], "taskspace")
    assert parse(["train"]).config.run_name == RUN_NAME  # tsrl/UR5eReach-v0: fs1 and taskspace


def test_the_run_folder_keeps_the_task_files_with_their_sha256(trained, task_file):
    folder = task_file.parent
    rows = json.loads((trained / "task" / "record.json").read_text())["files"]
    by_name = {Path(row["path"]).name: row for row in rows}
    assert {name: by_name[name]["roles"] for name in by_name} == {
        "task.toml": ["task"],
        "arm.toml": ["robot"],
        "arm.xml": ["robot model", "scene"],  # one file, both roles
    }
    for name, row in by_name.items():
        assert row["path"] == str(folder / name) and row["sha256"] == sha256(folder / name)
        assert (trained / "task" / row["copy"]).read_bytes() == (folder / name).read_bytes()
    # The copy of the task reads its robot file from the run's copy and its unchanged model where it lies.
    task = recorded_task(trained / "task" / "task.toml")
    assert task is not None and task.robot == str(trained / "task" / "arm.toml")
    assert task.scene == str(folder / "arm.xml")


def test_resume_after_the_originals_changed_uses_the_copies_and_says_so(trained, originals, tmp_path):
    run_dir = shutil.copytree(trained, tmp_path / trained.name)
    break_originals(originals)
    result = run_tsrl("train", "--resume", str(run_dir), "--total-timesteps", "400")
    assert result.returncode == 0, result.stderr
    lines = notices(result.stderr)
    assert len(lines) == 3, result.stderr
    for name in ("task.toml", "arm.toml", "arm.xml"):
        (line,) = [line for line in lines if str(originals / name) + " (" in line]
        assert f"changed since the run started; the run uses its copy {run_dir / 'task' / name}" in line
    with open(run_dir / "progress.csv", newline="") as f:
        rows = [(int(r["env_steps"]), int(r["episodes"])) for r in csv.DictReader(f)]
    assert rows[-1][0] >= 400
    assert all(steps == EPISODE_STEPS * episodes for steps, episodes in rows)  # the copy's 30-step episodes
    assert json.loads((run_dir / "config.json").read_text())["env_id"] == str(originals / "task.toml")


def test_evaluate_and_resume_use_the_copies_when_the_originals_are_gone(trained, originals, tmp_path):
    before = run_tsrl("evaluate", str(trained), "--episodes", "2")
    assert before.returncode == 0 and not notices(before.stderr), before.stderr
    (originals / "task.toml").unlink()
    (originals / "arm.toml").unlink()
    (originals / "arm.xml").write_text("<mujoco/>")
    after = run_tsrl("evaluate", str(trained), "--episodes", "2")
    assert after.returncode == 0, after.stderr
    assert after.stdout == before.stdout  # the same task: the same episodes, success and distance
    lines = notices(after.stderr)
    assert len(lines) == 3, after.stderr
    assert sum("is gone; the run uses its copy" in line for line in lines) == 2
    assert sum("arm.xml (robot model, scene) changed" in line for line in lines) == 1
    run_dir = shutil.copytree(trained, tmp_path / trained.name)
    resumed = run_tsrl("train", "--resume", str(run_dir), "--total-timesteps", "300")
    assert resumed.returncode == 0 and len(notices(resumed.stderr)) == 3, resumed.stderr


def test_a_run_folder_from_before_the_record_loads_and_resumes_with_one_notice(trained, tmp_path):
    run_dir = shutil.copytree(trained, tmp_path / trained.name)
    shutil.rmtree(run_dir / "task")
    for args in (["evaluate", str(run_dir), "--episodes", "2"], ["train", "--resume", str(run_dir), "--total-timesteps", "300"]):  # fmt: skip
        result = run_tsrl(*args)
        assert result.returncode == 0, result.stderr
        (line,) = notices(result.stderr)
        assert f"{run_dir} has no record of its task's files" in line and "as they are now" in line


def test_a_built_in_tasks_run_records_its_installed_files_and_notices_a_changed_one(tmp_path, capsys):
    cfg = TrainConfig()  # tsrl/UR5eReach-v0: its task, robot model and scene are tsrl's package data
    write_task_record(tmp_path, cfg)
    record = tmp_path / "task" / "record.json"
    rows = json.loads(record.read_text())["files"]
    assert [p.name for p in (tmp_path / "task").iterdir()] == ["record.json"]  # nothing copied
    assert all(row["copy"] is None and row["sha256"] == sha256(Path(row["path"])) for row in rows)
    assert rows[0]["path"] == str(builtin_task_path("UR5eReach-v0"))
    assert with_task_copy(tmp_path, cfg) == cfg and capsys.readouterr().err == ""
    rows[0]["sha256"] = "0" * 64  # as if another tsrl had been installed since
    record.write_text(json.dumps({"files": rows}))
    assert with_task_copy(tmp_path, cfg) == cfg
    (line,) = capsys.readouterr().err.splitlines()
    assert line == (
        f"tsrl: notice: {rows[0]['path']} (task, installed) changed since the run started "
        "(another tsrl or package?); the run reads it as it is now"
    )
