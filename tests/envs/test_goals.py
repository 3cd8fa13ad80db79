"""envs/goals.py: the one owner of success, reward, penalties and relabelling.

The step's reward equals `compute_reward` of its goals on every registered task (blow-ups and
penalties included, both reward conventions); a goal of two objects relabels exactly (relabel ==
moving both markers); goal rules that no draw can meet are one error naming the file and the key.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import tsrl
from tsrl.assets import scene_path
from tsrl.envs.base import TaskEnv
from tsrl.envs.tasks import GoalSpec, ObjectSampler, PositionSampler, SuccessSpec, Task, load_task
from tsrl.exceptions import InvalidConfig, UnknownName

STEPS = 1000


def _blow_up(env: TaskEnv) -> None:
    """A joint speed beyond MuJoCo's limit: the next step's physics warns and resets the state."""
    env.data.qvel[0] = 1e11


@pytest.mark.parametrize("reward", ["0/1", "-1/0"])
@pytest.mark.parametrize("env_id", tsrl.ENV_IDS)
def test_step_reward_equals_compute_reward_on_every_step(env_id, reward):
    task = load_task(env_id.removeprefix("tsrl/"))
    task = dataclasses.replace(task, success=dataclasses.replace(task.success, reward=reward))
    env = TaskEnv(task)
    rng = np.random.default_rng(0)
    env.action_space.seed(0)
    obs, info = env.reset(seed=0)
    seen = {"success": 0, "failure": 0, "penalty": 0, "unstable": 0}
    for step in range(STEPS):
        if step % 97 == 50:
            _blow_up(env)
        # Half the steps head for the goal's own value (the achieved goal of a reach task is the
        # TCP), so that successes occur, the others are random.
        action = rng.uniform(-1, 1, env.action_space.shape)
        if step % 2 and env.task.goal.map.startswith("position(tcp)"):
            direction = (obs["desired_goal"][:3] - obs["achieved_goal"][:3]) / 0.05
            action[:3] = np.clip(direction, -1, 1)
        obs, r, terminated, truncated, info = env.step(action)
        expected = env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
        assert r == expected, (step, r, expected, info)
        assert info["is_success"] == bool(env.goal.success(obs["achieved_goal"], obs["desired_goal"]))
        seen["success" if info["is_success"] else "failure"] += 1
        seen["penalty"] += bool(info.get("penalty", 0.0))
        seen["unstable"] += bool(info.get("physics_unstable", False))
        if terminated or truncated:
            obs, info = env.reset()
    env.close()
    assert seen["unstable"] >= 5 and seen["failure"] > 0
    if env.goal.penalties:
        assert seen["penalty"] > 0
    if env_id.endswith("Reach-v0") and "Pose" not in env_id:
        assert seen["success"] > 0


def test_batched_compute_reward_equals_single_goals():
    env = gym.make("tsrl/UR5eObstacleReach-v1").unwrapped
    rng = np.random.default_rng(1)
    obs, _ = env.reset(seed=1)
    achieved = np.repeat(obs["achieved_goal"][None], 64, axis=0)
    achieved[:, :3] += rng.normal(0, 0.05, (64, 3))
    achieved[::3, 3] = 0.01  # a penetration in every third goal
    desired = np.repeat(obs["desired_goal"][None], 64, axis=0)
    batched = env.compute_reward(achieved, desired, {})
    single = [env.compute_reward(a, d, {}) for a, d in zip(achieved, desired)]
    np.testing.assert_array_equal(batched, single)
    assert set(np.unique(batched)) >= {-1.0, 0.0}


def test_a_blow_up_step_returns_fresh_arrays_and_consistent_reward_and_info():
    env = gym.make("tsrl/UR5eReach-v0").unwrapped
    env.reset(seed=0)
    before, *_ = env.step(np.zeros(3))
    _blow_up(env)
    obs, r, terminated, truncated, info = env.step(np.zeros(3))
    assert info["physics_unstable"] and truncated and not terminated
    for key in obs:  # the last observation's values, in new arrays
        np.testing.assert_array_equal(obs[key], before[key])
        assert not np.shares_memory(obs[key], before[key])
    assert r == env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)


# -- a goal of two objects ---------------------------------------------------------------------------
TWO_BOXES = """<mujoco model="two_boxes">
  <include file="{ur5e}"/>
  <include file="{table}"/>
  <worldbody>
    <body name="box" pos="-0.5 -0.15 0.02"><freejoint/>
      <geom name="box" type="box" size="0.02 0.02 0.02" mass="0.1" contype="1" conaffinity="3"/></body>
    <body name="box_b" pos="-0.4 -0.15 0.02"><freejoint/>
      <geom name="box_b" type="box" size="0.02 0.02 0.02" mass="0.1" contype="1" conaffinity="3"/></body>
    <body name="target" mocap="true" pos="-0.5 0.1 0.2"><site name="target" size="0.01"/></body>
    <body name="target_b" mocap="true" pos="-0.5 0.1 0.24"><site name="target_b" size="0.01"/></body>
  </worldbody>
</mujoco>
"""
TWO_BOX_OBS = (
    "position(tcp), position(box), position(box_b), position(target), position(target_b), "
    "positionDiff(box, target), positionDiff(box_b, target_b), positionDiff(target_b, target), "
    "positionDiff(tcp, target_b), velocity(positionDiff(box_b, target_b))"
)


def _two_box_task(tmp_path: Path, **goal) -> Task:
    scene = tmp_path / "two_boxes.xml"
    scene.write_text(
        TWO_BOXES.format(ur5e=scene_path("ur5e"), table=scene_path("pick_place").parent / "table.xml")
    )
    box = ((-0.49, -0.13, 0.02), (0.15, 0.15, 0.0))
    spec = {
        "map": "position(box), position(box_b)",
        "position": PositionSampler(*box),
        "offsets": ((0, 0, 0.04),),
    }
    return Task(
        name="TwoBoxes",
        scene=str(scene),
        goal=GoalSpec(**(spec | goal)),
        observation=TWO_BOX_OBS,
        objects=(ObjectSampler("box", *box), ObjectSampler("box_b", *box)),
        success=SuccessSpec(position=0.02),
    )


def test_a_two_object_goal_relabels_exactly_as_moving_both_markers(tmp_path):
    env = TaskEnv(_two_box_task(tmp_path))
    assert env.observation_space["desired_goal"].shape == (6,)
    obs, _ = env.reset(seed=3)
    np.testing.assert_allclose(obs["desired_goal"][3:] - obs["desired_goal"][:3], [0, 0, 0.04])
    rng = np.random.default_rng(0)
    for _ in range(5):
        obs, *_ = env.step(rng.uniform(-1, 1, 3))
    new_goals = obs["desired_goal"] + rng.normal(0, 0.1, (8, 6))
    batched = env.relabel({k: np.repeat(v[None], 8, axis=0) for k, v in obs.items()}, new_goals)
    for i, goal in enumerate(new_goals):
        relabelled = env.relabel(obs, goal)
        observed = env.move_target(goal)
        np.testing.assert_allclose(relabelled["observation"], observed["observation"], atol=1e-12)
        np.testing.assert_allclose(batched["observation"][i], observed["observation"], atol=1e-12)
        np.testing.assert_array_equal(relabelled["desired_goal"], observed["desired_goal"])
        np.testing.assert_array_equal(relabelled["achieved_goal"], obs["achieved_goal"])
    env.close()


def test_a_two_object_goal_succeeds_only_when_both_parts_are_within_tolerance(tmp_path):
    env = TaskEnv(_two_box_task(tmp_path))
    goal = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.04])
    near, far = 0.019, 0.021  # the tolerance is 0.02 m
    cases = {
        (near, near): True,
        (near, far): False,
        (far, near): False,
    }
    for (a, b), success in cases.items():
        achieved = goal + [a, 0, 0, 0, b, 0]
        assert bool(env.goal.success(achieved, goal)) is success
        reward, info = env.goal.outcome(achieved, goal)
        assert reward == float(success) and info["is_success"] is success
        assert info["distance"] == pytest.approx(max(a, b))


def test_a_two_object_goal_needs_one_offset_per_later_part(tmp_path):
    with pytest.raises(InvalidConfig, match=r"goal.offsets has 0 entries for a goal of 2 parts"):
        TaskEnv(_two_box_task(tmp_path, offsets=()))


# -- bad input ----------------------------------------------------------------------------------------
def test_a_min_distance_no_draw_can_meet_is_one_error_naming_the_file_and_key(tmp_path):
    text = (
        load_task("UR5ePickPlace-v0").source.read_text().replace("min_distance = 0.1", "min_distance = 5.0")
    )
    path = tmp_path / "far.toml"
    path.write_text(text)
    env = gym.make("tsrl/Task-v0", task=path)
    with pytest.raises(InvalidConfig) as err:
        env.reset(seed=0)
    message = str(err.value)
    assert "\n" not in message and str(path) in message and "goal.position.min_distance = 5.0" in message


def test_an_unknown_frame_in_a_task_file_names_the_file(tmp_path):
    text = load_task("UR5eReach-v0").source.read_text()
    path = tmp_path / "typo.toml"
    path.write_text(text.replace('map = "position(tcp)"', 'map = "position(tpc)"', 1))
    with pytest.raises(UnknownName) as err:
        TaskEnv(path)
    assert str(err.value).startswith(f"{path}: ") and "'tpc'" in str(err.value)


def test_a_stacking_goal_whose_boxes_overlap_is_one_line_naming_the_key():
    task = load_task("PandaStack-v0")
    inside = dataclasses.replace(task, goal=dataclasses.replace(task.goal, offsets=((0.0, 0.0, 0.03),)))
    with pytest.raises(InvalidConfig) as err:
        TaskEnv(inside)
    message = str(err.value)
    assert "\n" not in message and str(task.source) in message
    assert "goal.offsets put 'box_b' inside 'box'" in message and "keep the objects apart" in message
    TaskEnv(task)  # 4 cm up: the boxes touch, one on the other


def test_a_stack_task_starts_with_the_boxes_apart_and_its_goals_stacked():
    env = TaskEnv("PandaStack-v0")
    for seed in range(30):
        obs, _ = env.reset(seed=seed)
        box, box_b = obs["achieved_goal"][:3], obs["achieved_goal"][3:]
        assert np.linalg.norm(box - box_b) >= 0.08
        np.testing.assert_allclose(obs["desired_goal"][3:] - obs["desired_goal"][:3], [0, 0, 0.04])
        for start in (box, box_b):
            assert np.linalg.norm(obs["desired_goal"][:3] - start) >= 0.1


def test_a_fixture_moves_with_the_goal_and_must_be_a_mocap_body(tmp_path):
    env = TaskEnv("PandaPegInsert-v0")
    fixture = env.model.body("fixture").mocapid[0]
    for seed in range(5):
        obs, _ = env.reset(seed=seed)
        np.testing.assert_allclose(env.data.mocap_pos[fixture], obs["desired_goal"][:3] + [0.0, 0.0, -0.04])
    task = load_task("PandaPegInsert-v0")
    bad = dataclasses.replace(task, fixtures=(dataclasses.replace(task.fixtures[0], body="peg"),))
    with pytest.raises(InvalidConfig, match="fixture body 'peg' must be a mocap body"):
        TaskEnv(bad)


def test_the_reward_scale_rewards_only_within_its_fraction_and_success_stays_at_the_tolerance(tmp_path):
    env = TaskEnv(_two_box_task(tmp_path), reward_scale=0.5)  # tolerance 0.02 m: rewarded within 0.01
    goal = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.04])
    cases = {0.009: (True, True), 0.011: (True, False), 0.019: (True, False), 0.021: (False, False)}
    for d, (success, rewarded) in cases.items():
        achieved = goal + [d, 0, 0, 0, 0.5 * d, 0]
        reward, info = env.goal.outcome(achieved, goal)
        assert info["is_success"] is success and bool(env.goal.success(achieved, goal)) is success, d
        assert (
            reward
            == float(rewarded)
            == env.goal.reward(achieved, goal)
            == env.compute_reward(achieved, goal, info)
        )
        assert env.goal.task_reward(achieved, goal) == float(success)  # what a demonstration file stores
    # Batched as HER relabels, and the same at scale 1 as the task's reward (nothing changes there).
    rng = np.random.default_rng(0)
    achieved = goal + rng.uniform(-0.03, 0.03, (500, 6))
    goals = np.repeat(goal[None], 500, axis=0)
    distance = np.maximum(
        np.linalg.norm(achieved[:, :3], axis=1), np.linalg.norm(achieved[:, 3:] - goal[3:], axis=1)
    )
    np.testing.assert_array_equal(env.goal.reward(achieved, goals), distance < 0.01)
    np.testing.assert_array_equal(env.goal.task_reward(achieved, goals), distance < 0.02)
    assert (
        0 < (distance < 0.01).sum() < (distance < 0.02).sum() < 500
    )  # all three kinds drawn: the test can fail
    plain = TaskEnv(_two_box_task(tmp_path))
    np.testing.assert_array_equal(plain.goal.reward(achieved, goals), plain.goal.task_reward(achieved, goals))
    env.close()
    plain.close()


@pytest.mark.parametrize("scale", [0, -0.5, 1.5, float("nan"), True])
def test_a_reward_scale_outside_0_1_is_refused_in_one_line(tmp_path, scale):
    with pytest.raises(InvalidConfig, match=r"reward_scale") as err:
        TaskEnv(_two_box_task(tmp_path), reward_scale=scale)
    assert "\n" not in str(err.value)


def test_the_reward_scale_applies_to_a_pose_goals_orientation_tolerance_too():
    env = TaskEnv("UR5ePoseReach-v0", reward_scale=0.5)
    tolerance = env.task.success.orientation  # deg
    goal = np.array([0.3, 0.2, 0.4, 1.0, 0.0, 0.0, 0.0])
    for angle, (success, rewarded) in {0.4: (True, True), 0.6: (True, False), 1.1: (False, False)}.items():
        half = np.radians(angle * tolerance) / 2
        achieved = goal.copy()
        achieved[3:] = [np.cos(half), 0.0, 0.0, np.sin(half)]  # turned about z by angle x tolerance
        reward, info = env.goal.outcome(achieved, goal)
        assert info["is_success"] is success and reward == float(rewarded), angle
        assert info["angle"] == pytest.approx(angle * tolerance)
    env.close()
