"""The bad-input battery's task, robot and demonstration files (issue 53; signals and run folders are
in test_fault_battery.py): each input a new user might try is refused before any work starts with one
line (exit code 2) naming the file, the key, the value and what is accepted. Tiny budgets."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_runner import run_tsrl

from tsrl.envs.tasks import builtin_task_path

REACH = builtin_task_path("UR5eReach-v0").read_text()
PICK = builtin_task_path("UR5ePickPlace-v0").read_text()


def _refused(done, *words: str) -> str:
    """The one line of a refusal (exit code 2), checked to hold each of `words`."""
    assert done.returncode == 2, (done.returncode, done.stdout[-2000:], done.stderr[-2000:])
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def _task(tmp_path: Path, text: str, name: str = "bad.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# -- task files: counts and sizes have upper bounds; bad values are one line ----------------------
@pytest.mark.parametrize(
    ("source", "old", "new", "words"),
    [
        (REACH, "episode_steps = 50", "episode_steps = 100000000000", ["episode_steps", "at most 10,000"]),
        (REACH, "episode_steps = 50", "episode_steps = 0", ["episode_steps", "> 0"]),
        (REACH, "control_dt = 0.04", "control_dt = 100000.0", ["control_dt", "at most 1 s"]),
        (REACH, "position = 0.05", "position = 1e300", ["success.position", "1e+300", "at most 10 m"]),
        (REACH, "episode_steps = 50", "episode_steps = 500\nprevious_actions = 400", ["previous_actions", "to 100"]),
        (PICK, 'body = "box"', 'body = "box"\nmin_separation = -0.1', ["min_separation", "-0.1", ">= 0"]),
        (REACH, 'reward = "0/1"', 'reward = "0/1"\n\n[randomize]\nobject_mass = [0.5, 2.0]', ["object_mass", "no [[objects]]"]),
    ],
)  # fmt: skip
def test_a_bad_task_file_value_is_one_line_before_training(tmp_path, source, old, new, words):
    assert old in source
    path = _task(tmp_path, source.replace(old, new, 1))
    out = tmp_path / "out"
    _refused(
        run_tsrl("train", "--task", str(path), "--total-timesteps", "100", "--out-dir", str(out)),
        str(path),
        *words,
    )
    assert not out.exists()


def test_too_many_objects_say_the_bound(tmp_path):
    tables = "".join(
        '\n[[objects]]\nbody = "box"\ncenter = [0, 0, 0]\nhalf_extent = [0, 0, 0]\n' for _ in range(33)
    )
    path = _task(tmp_path, PICK + tables)
    _refused(run_tsrl("train", "--task", str(path), "--out-dir", str(tmp_path)), "[[objects]]", "at most 32")


@pytest.mark.parametrize("value", ["-1", "0"])
def test_a_scale_perturbation_of_zero_or_less_says_the_same_bound(value):
    from tsrl.agents.transfer import parse_perturb
    from tsrl.exceptions import InvalidConfig

    with pytest.raises(InvalidConfig) as err:
        parse_perturb(f"object_friction={value}")
    assert f"object_friction = {value}; accepted: values > 0" in str(err.value)


# -- frame = "base" follows the robot file's `base` key -------------------------------------------
def _own_arm_in_base_frame(tmp_path: Path, base: str | None) -> Path:
    """The docs' ten-line arm (its moving first body is named `base`) on a task with frame = "base"."""
    from own_task import write_task

    task = write_task(tmp_path)
    task.write_text(task.read_text().replace('scene = "arm.xml"', 'scene = "arm.xml"\nframe = "base"'))
    if base is not None:
        robot = tmp_path / "arm.toml"
        robot.write_text(robot.read_text() + f'base = "{base}"\n')
    return task


def test_frame_base_uses_the_robot_files_base_key_over_a_moving_body_named_base(tmp_path):
    import gymnasium as gym
    import numpy as np

    from tsrl.envs import TASK_ENV_ID

    env = gym.make(TASK_ENV_ID, task=str(_own_arm_in_base_frame(tmp_path, "world")), max_episode_steps=5)
    u = env.unwrapped
    env.reset(seed=0)
    site = u.model.site("base").id
    assert u.model.site_bodyid[site] == 0 and np.allclose(u.data.site_xpos[site], 0)  # at the world's origin
    assert u.model.body("base").id > 0  # the arm's own body `base` is still there


def test_frame_base_on_a_moving_base_names_the_robot_files_base_key(tmp_path):
    task = _own_arm_in_base_frame(tmp_path, None)
    _refused(
        run_tsrl("train", "--task", str(task), "--out-dir", str(tmp_path / "out")),
        "moves with a joint",
        "`base` key",
    )


def test_robot_check_with_a_gripper_actuator_the_model_lacks_is_one_line(tmp_path):
    from own_task import write_task

    write_task(tmp_path)
    robot = tmp_path / "arm.toml"
    robot.write_text(robot.read_text() + 'gripper = "hand"\n')
    _refused(run_tsrl("robot", "check", str(robot)), str(robot), "gripper", "'hand'", "elbow, shoulder, yaw")


def test_a_goal_box_beyond_the_arms_reach_is_one_line_even_without_action_bounds(tmp_path):
    """The ten-line arm (0.8 m from its first joint to its tool; its position action has no bounds)
    asked for goals 2 m away."""
    from own_task import write_task

    task = write_task(tmp_path)
    text = task.read_text()
    assert "low" not in text and "center = [0.6, 0.0, 0.3]" in text
    task.write_text(text.replace("center = [0.6, 0.0, 0.3]", "center = [2.0, 0.0, 0.3]"))
    _refused(
        run_tsrl("train", "--task", str(task), "--out-dir", str(tmp_path / "out")),
        str(task),
        "goal.position",
        "2.10 m from the arm's first joint",
        "'tool' reaches at most 0.80 m",
    )


# -- demonstrations carry their task's identity and the task's rewards ---------------------------
@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory):
    """Two scripted episodes on a copy of the reach's task file, saved as .npz."""
    from tsrl.agents.demo_files import save_demos
    from tsrl.agents.demonstrators import record_demos

    folder = tmp_path_factory.mktemp("demos")
    task = _task(
        folder,
        REACH.replace('name = "UR5eReach-v0"', 'name = "MyReach"\nsolver = "UR5eReach-v0"'),
        "my_reach.toml",
    )
    demos = record_demos(str(task), 2)
    assert demos.meta["task_sha256"] and demos.n_episodes == 2
    return task, demos, save_demos(demos, folder / "reach.npz")


def _train_with_demos(task: Path, demos: Path, out: Path):
    return run_tsrl(
        "train", "--task", str(task), "--demos", str(demos), "--total-timesteps", "100", "--out-dir", str(out)
    )


def test_demonstrations_of_another_task_file_with_the_same_observation_are_refused(reach_demos, tmp_path):
    _, _, demos = reach_demos
    other = _task(
        tmp_path, REACH.replace("half_extent = [0.15, 0.15, 0.15]", "half_extent = [0.05, 0.05, 0.05]")
    )
    _refused(
        _train_with_demos(other, demos, tmp_path / "out"), str(demos), "task file sha256", "another task file"
    )
    assert not (tmp_path / "out").exists()


def test_demonstrations_carry_the_digests_of_the_files_their_task_reads_and_a_change_is_refused(
    reach_demos, tmp_path
):
    import dataclasses
    import hashlib

    from tsrl.agents.demo_files import save_demos
    from tsrl.agents.task_record import task_files

    task, demos, _ = reach_demos
    files = {"+".join(f.roles): f.path for f in task_files(task) if "task" not in f.roles}
    assert set(files) == {"robot model", "scene"}  # the UR5e's MJCF and the reach's scene
    assert demos.meta["task_files"] == {
        r: hashlib.sha256(p.read_bytes()).hexdigest() for r, p in files.items()
    }
    # Recorded while the robot model was another file: refused, naming it.
    meta = demos.meta | {"task_files": demos.meta["task_files"] | {"robot model": "0" * 64}}
    moved = save_demos(dataclasses.replace(demos, meta=meta), tmp_path / "moved.npz")
    _refused(
        _train_with_demos(task, moved, tmp_path / "out"),
        str(moved),
        "robot model file sha256 000000000000",
        "changed since the recording",
    )
    assert not (tmp_path / "out").exists()


def test_demonstrations_whose_rewards_are_not_the_tasks_are_refused(reach_demos, tmp_path):
    import dataclasses

    import numpy as np

    from tsrl.agents.demo_files import save_demos

    task, demos, _ = reach_demos
    edited = save_demos(
        dataclasses.replace(demos, rewards=np.full_like(demos.rewards, 7.0)), tmp_path / "r.npz"
    )
    _refused(_train_with_demos(task, edited, tmp_path / "out"), "rewards are not the task's", "stored 7")


def test_demonstrations_without_a_task_hash_still_load(reach_demos, tmp_path):
    import dataclasses

    import gymnasium as gym

    from tsrl.agents.demo_files import DemoSpec, load_demos, save_demos
    from tsrl.envs import TASK_ENV_ID

    _, demos, _ = reach_demos  # a file from before the hash was kept: another task file is not told apart
    old = {k: v for k, v in demos.meta.items() if k != "task_sha256"}
    path = save_demos(dataclasses.replace(demos, meta=old), tmp_path / "old.npz")
    other = _task(
        tmp_path, REACH.replace("half_extent = [0.15, 0.15, 0.15]", "half_extent = [0.05, 0.05, 0.05]")
    )
    assert load_demos(path, DemoSpec.of(gym.make(TASK_ENV_ID, task=str(other)))).n_episodes == 2


# -- an experiment file's [[evaluate]] errors name its keys, not the command line's flags ----------
@pytest.mark.parametrize(
    ("perturb", "words"),
    [
        ('{ key = "action_latency", values = [60] }', ["[evaluate[0]] perturbation action_latency=60", "0 to 49"]),
        ('{ key = "object_friction", values = [0] }', ["[evaluate[0].perturb]", "object_friction = 0", "> 0"]),
    ],
)  # fmt: skip
def test_an_experiment_files_bad_perturbation_names_the_file_and_key_not_the_flag(tmp_path, perturb, words):
    definition = _task(
        tmp_path,
        'env = ["tsrl/UR5eReach-v0"]\nobs = ["fs1"]\nseeds = [0]\ntotal_timesteps = 200\n\n[[evaluate]]\n'
        f'name = "bad"\narm = "fs1"\nenv = "tsrl/UR5eReach-v0"\nepisodes = 3\nperturb = {perturb}\n',
        "exp.toml",
    )
    line = _refused(
        run_tsrl("experiment", str(definition), "--out-dir", str(tmp_path / "out")), str(definition), *words
    )
    assert "--perturb" not in line and not (tmp_path / "out").exists()
