"""tsrl.experiments.failures: which goal objects it classes, the classes of hand-made paths, its table's
columns, and the rows of a seconds-long run."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from training_helpers import tiny

from tsrl.agents.evaluation import fresh_eval_seeds
from tsrl.agents.factory import make_env
from tsrl.agents.training import train
from tsrl.envs import load_task
from tsrl.envs.base import TaskEnv
from tsrl.experiments import failures


@pytest.mark.parametrize(
    ("task", "expected"),
    [
        ("PandaPush-v0", [("box", slice(0, 3))]),
        ("PandaStack-v0", [("box", slice(0, 3)), ("box_b", slice(3, 6))]),
        ("PandaPegInsert-v0", [("peg", slice(0, 3))]),
    ],
)
def test_goal_objects_are_the_goal_positions_bodies_and_their_goal_slices(
    task: str, expected: list[tuple[str, slice]]
) -> None:
    env = TaskEnv(task)
    try:
        objects = failures.goal_objects(env)
        obs, _ = env.reset(seed=3)
        for body, part in objects:  # each slice is that body's goal: the achieved goal holds its position
            np.testing.assert_allclose(obs["achieved_goal"][part], env.data.body(body).xpos, atol=1e-12)
    finally:
        env.close()
    assert objects == expected


@pytest.mark.parametrize("spec", ["positionDiff(box, target)", "velocity(position(box))", "quaternion(peg)"])
def test_a_goal_without_a_body_position_is_refused(spec: str) -> None:
    task = SimpleNamespace(name="X-v0", goal=SimpleNamespace(map=spec))
    with pytest.raises(ValueError, match="X-v0: goal map .* failure classes need a goal of position"):
        failures.goal_objects(SimpleNamespace(task=task))


def test_classes_of_hand_made_paths() -> None:
    start, goal, tol = np.zeros(3), np.array([0.2, 0.0, 0.0]), 0.02
    line = np.linspace(start, goal, 10)
    assert failures.classify(start, line, goal, tol) == "success"
    assert failures.classify(start, np.zeros((10, 3)) + 0.001, goal, tol) == "not moved"
    assert failures.classify(start, np.vstack([line, line[::-1]]), goal, tol) == "reached, then lost"
    assert failures.classify(start, line[:7], goal, tol) == "short of the goal"
    assert failures.classify(start, -line, goal, tol) == "moved, not towards the goal"


def test_stalled_is_a_tcp_still_over_the_last_steps() -> None:
    n = failures.STALL_STEPS
    moving = np.linspace([0.0, 0.0, 0.0], [0.3, 0.0, 0.0], 3 * n)
    assert not failures.stalled(moving)
    still_at_end = np.vstack([moving, np.repeat(moving[-1:], n, axis=0)])  # n steps at the last place
    assert failures.stalled(still_at_end)
    jitter = still_at_end.copy()
    jitter[-1, 1] += 2 * failures.STALL_MOVE  # the last step moves 2 mm: not still
    assert not failures.stalled(jitter)
    assert not failures.stalled(np.zeros((n, 3)))  # too short to say


def test_at_bound_is_within_half_a_percent_of_the_range_from_either_end() -> None:
    low, high = np.array([-1.0, 0.0]), np.array([1.0, 0.08])  # a [-1, 1] part and a width in m
    actions = np.array(
        [
            [-1.0, 0.0],  # both at their lower bounds
            [0.995, 0.0798],  # both within 0.5 % of the range of the upper bound
            [0.985, 0.0795],  # both just outside that margin
            [0.0, 0.04],  # both in the middle
        ]
    )
    expected = np.array([[True, True], [True, True], [False, False], [False, False]])
    np.testing.assert_array_equal(failures.at_bound(actions, low, high), expected)


#: A data row of `failure_modes` as saved before the optional columns were measured.
ROW = {
    "run": "r",
    "env_steps": 100,
    "episodes": 4,
    **dict.fromkeys(failures.CLASSES, 1),
    "median_steps_to_success": 3.0,
    "failed_stalled": 0,
}


def test_render_shows_the_bound_column_only_where_every_row_has_it() -> None:
    row = ROW
    assert "at a bound" not in failures.render([row])[0]
    lines = failures.render([{**row, "actions_at_bound": 0.375}])
    assert lines[0].endswith("| actions at a bound |")
    assert lines[2].endswith("| 0 | 38% |")


def test_touches_is_a_contact_between_the_body_and_a_tree() -> None:
    env = TaskEnv("PandaPickPlaceGripper-v0")
    try:
        env.reset(seed=0)
        model, data = env.model, env.data
        box = model.body("box").id
        robot = int(model.body_rootid[model.body("finger_left").id])
        mujoco.mj_forward(model, data)
        assert failures.touches(model, data, box, 0)  # resting on the table, a world geom
        assert not failures.touches(model, data, box, robot)  # at reset, clear of the hand
        joint = model.body_jntadr[box]
        data.qpos[model.jnt_qposadr[joint] : model.jnt_qposadr[joint] + 3] = data.body("finger_left").xpos
        mujoco.mj_forward(model, data)  # the box's centre inside the left finger: in contact
        assert failures.touches(model, data, box, robot)
        assert not failures.touches(model, data, box, int(model.body_rootid[model.body("target").id]))
    finally:
        env.close()


def test_render_shows_the_touching_columns_only_where_every_row_has_them() -> None:
    row = {**ROW, "actions_at_bound": 0.375}
    assert "touching" not in failures.render([row])[0]
    lines = failures.render([{**row, "lost_touching": 1}, {**row, "lost_touching": 0}])
    assert lines[0].endswith("| lost, ended touching the robot | actions at a bound |")
    assert lines[2].endswith("| 0 | 1 | 38% |") and lines[3].endswith("| 0 | 0 | 38% |")
    lines = failures.render([{**row, "lost_touching": 0, "lost_held": 1}])
    assert lines[0].endswith(
        "| lost, ended touching the robot | lost, held when last at the goal | actions at a bound |"
    )
    assert lines[2].endswith("| 0 | 0 | 1 | 38% |")


def test_lifted_is_a_goal_more_than_a_centimetre_above_the_start() -> None:
    start = np.array([-0.4, 0.1, 0.02])
    assert not failures.lifted(start, start + [0.2, -0.1, 0.0])  # on the table
    assert not failures.lifted(start, start + [0.0, 0.0, 0.009])
    assert failures.lifted(start, start + [0.0, 0.0, 0.011])
    assert not failures.lifted(start, start - [0.0, 0.0, 0.2])  # below: not lifted


def test_render_shows_the_lifted_column_only_where_every_row_has_its_counts() -> None:
    row = {**ROW, "actions_at_bound": 0.375}
    counts = {"lifted_goals": 48, "failed_lifted": 20, "lost_lifted": 9}
    assert "lifted" not in failures.render([row, {**row, **counts}])[0]
    assert "lifted" not in failures.render([{**row, "lifted_goals": 48, "failed_lifted": 20}])[0]
    lines = failures.render([{**row, **counts}])
    assert lines[0].endswith("| goal lifted: episodes, failed, reached then lost | actions at a bound |")
    assert lines[2].endswith("| 0 | 48, 20, 9 | 38% |")


def test_render_leaves_out_the_lifted_column_where_no_goal_was_lifted() -> None:
    """A push's goals lie on the table: its rows' lifted counts are all zero, and the column is noise."""
    row = {**ROW, "actions_at_bound": 0.375}
    never = {"lifted_goals": 0, "failed_lifted": 0, "lost_lifted": 0}
    assert "lifted" not in failures.render([{**row, **never}, {**row, **never}])[0]
    once = {"lifted_goals": 1, "failed_lifted": 0, "lost_lifted": 0}
    assert "lifted" in failures.render([{**row, **never}, {**row, **once}])[0]


def test_a_gripper_runs_rows_count_its_episodes_and_lifted_goals(tmp_path) -> None:
    """A seconds-long run on the gripper pick-and-place: the classes partition the episodes, and the
    lifted-goal counts match the goals of the same fresh evaluation seeds counted here."""
    task_file = str(load_task("PandaPickPlaceGripper-v0").source)
    cfg = dataclasses.replace(tiny(total=100), env_id=task_file)
    run = train(cfg, tmp_path, progress_bar=False)
    episodes = 8
    (row,) = failures.failure_modes(run, episodes, lambda config: [f"seed {config['seed']}"])
    assert sum(row[c] for c in failures.CLASSES) == episodes
    assert row["run"] == f"{run.name} (seed 0)"  # what `describe` says of the run's config
    env = make_env(cfg)
    expected = 0
    for seed in fresh_eval_seeds(cfg.seed, episodes):
        obs, _ = env.reset(seed=seed)
        expected += obs["desired_goal"][2] - env.unwrapped.data.body("box").xpos[2] > 0.01
    env.close()
    assert 0 < expected < episodes  # half the goals are lifted: the check can fail either way
    assert row["lifted_goals"] == expected
    assert row["lost_lifted"] <= row["failed_lifted"] <= row["lifted_goals"]
    assert row["lost_lifted"] <= row["reached, then lost"]
