"""Observation presets, their structure, and HER relabelling against the environment itself."""

import itertools

import gymnasium as gym
import numpy as np
import pytest

import tsrl  # noqa: F401

#: Tasks whose goal is one position (3,); pose and penalty goals: tests/envs/test_tasks.py.
POSITION_GOAL_ENV_IDS = ("tsrl/UR5eReach-v0", "tsrl/UR5ePickPlace-v0")
from tsrl.taskmaps import parse_spec

PRESET_DIMS = [("baseline", 6), ("simple", 6), ("fs0", 9), ("fs1", 15), ("fs2", 23)]


@pytest.mark.parametrize(("name", "dim"), PRESET_DIMS)
def test_preset_dimension_and_structure(name, dim):
    env = gym.make("tsrl/UR5eReach-v0", obs=name)
    obs, _ = env.reset(seed=0)
    assert obs["observation"].shape == (dim,)
    spans = sorted(env.unwrapped.observation_structure.values(), key=lambda s: s.start)
    assert spans[0].start == 0 and spans[-1].stop == dim
    assert all(a.stop == b.start for a, b in itertools.pairwise(spans))


def test_fs1_structure_follows_the_design_order():
    env = gym.make("tsrl/UR5eReach-v0", obs="fs1")
    assert list(env.unwrapped.observation_structure) == [
        "position(tcp)",
        "position(target)",
        "positionDiff(tcp, target)",
        "velocity(position(tcp))",
        "velocity(positionDiff(tcp, target))",
    ]


def test_spec_string_observation():
    env = gym.make("tsrl/UR5eReach-v0", obs="positionDiff(tcp, target), scalarProductZZ(world, tcp)")
    obs, _ = env.reset(seed=0)
    assert obs["observation"].shape == (4,)
    np.testing.assert_allclose(obs["observation"][:3], obs["achieved_goal"] - obs["desired_goal"])


@pytest.mark.parametrize("env_id", POSITION_GOAL_ENV_IDS)
@pytest.mark.parametrize(
    ("preset", "action"),
    [("fs2", "taskspace"), ("simple", "taskspace"), ("fs1", "taskspace_orient"), ("fs0", "joint")],
)
def test_step_evaluates_each_map_once_and_reads_goals_and_ik_values_off_it(env_id, preset, action):
    env = gym.make(env_id, obs=preset, action=action).unwrapped
    specs = [p.spec for p in env.plan._maps.parts]
    assert len(specs) == len(set(specs))
    obs = moved_state_observation(env, seed=2)
    model, data = env.model, env.data
    goals = parse_spec(f"{env.task.goal.map}, position(target)", model)(model, data).y
    np.testing.assert_array_equal(obs["achieved_goal"], goals[:3])
    np.testing.assert_array_equal(obs["desired_goal"], goals[3:])
    ik_map = env.action_map.ik_map
    if ik_map is not None:  # the next IK starts from the ik map's own value at this state
        expected = ik_map(model, data)
        np.testing.assert_array_equal(env.plan.ik_value.y, expected.y)
        np.testing.assert_array_equal(env.plan.ik_value.J, expected.J)


def moved_state_observation(env, seed, steps=4):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    for _ in range(steps):
        obs, *_ = env.step(env.action_space.sample())
    return obs


@pytest.mark.parametrize("env_id", POSITION_GOAL_ENV_IDS)
@pytest.mark.parametrize("preset", ["fs0", "fs1", "fs2", "simple"])
def test_relabelled_observation_equals_env_observation(env_id, preset):
    env = gym.make(env_id, obs=preset).unwrapped
    obs = moved_state_observation(env, seed=1)
    new_goal = obs["desired_goal"] + np.array([0.07, -0.05, 0.03])
    relabelled = env.relabel(obs, new_goal)
    observed = env.move_target(new_goal)
    for key in ("observation", "achieved_goal", "desired_goal"):
        np.testing.assert_allclose(relabelled[key], observed[key], atol=1e-12)


def test_batched_relabel_equals_single_relabels():
    env = gym.make("tsrl/UR5eReach-v0", obs="fs2").unwrapped
    singles = [moved_state_observation(env, seed=s) for s in range(4)]
    batch = {k: np.stack([o[k] for o in singles]) for k in singles[0]}
    new_goals = np.random.default_rng(0).uniform(-0.5, 0.5, (4, 3))
    batched = env.relabel(batch, new_goals)
    for i, obs in enumerate(singles):
        single = env.relabel(obs, new_goals[i])
        for key in single:
            np.testing.assert_allclose(batched[key][i], single[key], atol=1e-12)


def test_relabel_to_the_achieved_goal_makes_the_difference_zero():
    env = gym.make("tsrl/UR5eReach-v0", obs="simple").unwrapped
    obs = moved_state_observation(env, seed=2)
    relabelled = env.relabel(obs, obs["achieved_goal"])
    np.testing.assert_allclose(relabelled["observation"][:3], 0.0, atol=1e-12)
    assert env.compute_reward(relabelled["achieved_goal"], relabelled["desired_goal"], {}) == 1.0
