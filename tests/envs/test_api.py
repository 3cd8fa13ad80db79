"""The Gymnasium contract on every registered id: checkers, determinism, pickling, invariants."""

import pickle

import gymnasium as gym
import numpy as np
import pytest
import stable_baselines3.common.env_checker as sb3_checker
from gymnasium.utils.env_checker import check_env

import tsrl  # registers the environments
from tsrl.envs import ENV_IDS, load_task


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_env_passes_both_checkers(env_id):
    env = gym.make(env_id).unwrapped
    check_env(env, skip_render_check=True)
    sb3_checker.check_env(env, warn=True)
    env.close()


def rollout(env, seed, steps=20):
    obs, _ = env.reset(seed=seed)
    env.action_space.seed(seed)
    trace = [obs["observation"]]
    for _ in range(steps):
        obs, reward, *_ = env.step(env.action_space.sample())
        trace.append(np.concatenate([obs["observation"], obs["achieved_goal"], [reward]]))
    return trace


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_gives_identical_rollouts(env_id):
    a, b = gym.make(env_id, obs="fs1"), gym.make(env_id, obs="fs1")
    for x, y in zip(rollout(a, 3), rollout(b, 3), strict=True):
        np.testing.assert_array_equal(x, y)


def _fs2_or_own(env_id: str) -> str | None:
    """fs2, unless the goal is an object's pose: then fs2's quaternionDiff(tcp, target) cannot be
    relabelled (the goal does not carry the TCP's orientation) and the task's own observation is used."""
    goal = load_task(env_id.removeprefix("tsrl/")).goal.map
    return "fs2" if "quaternion" not in goal or goal.startswith("position(tcp)") else None


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_pickle_round_trip(env_id):
    env = gym.make(env_id, obs=_fs2_or_own(env_id), action="taskspace_orient")
    clone = pickle.loads(pickle.dumps(env))
    assert clone.unwrapped.obs_spec == env.unwrapped.obs_spec
    assert clone.action_space == env.action_space
    for x, y in zip(rollout(env, 1, 5), rollout(clone, 1, 5), strict=True):
        np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_observations_do_not_share_memory(env_id):
    env = gym.make(env_id, obs="fs1")
    first, _ = env.reset(seed=0)
    second, *_ = env.step(env.action_space.sample())
    for key in first:
        assert not np.shares_memory(first[key], second[key])


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_resets_give_different_goals_and_episodes_last_their_task_files_steps(env_id):
    env = gym.make(env_id)
    goals = [env.reset(seed=s)[0]["desired_goal"] for s in range(5)]
    assert len({tuple(g) for g in goals}) == 5
    env.reset(seed=0)
    steps = load_task(env_id.removeprefix("tsrl/")).episode_steps  # 50 (2 s) for most tasks
    for step in range(1, steps + 1):
        *_, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        assert "is_success" in info and "distance" in info and "ik_error" in info
        assert not terminated
        assert truncated == (step == steps)


def test_no_observation_element_is_constant_across_episodes():
    env = gym.make("tsrl/UR5eReach-v0", obs="fs1")
    env.action_space.seed(0)
    rows = []
    for seed in range(3):
        env.reset(seed=seed)
        for _ in range(5):
            rows.append(env.step(env.action_space.sample())[0]["observation"])
    assert np.all(np.ptp(np.array(rows), axis=0) > 0)


def test_reward_is_one_on_success_else_zero():
    env = gym.make("tsrl/UR5eReach-v0").unwrapped
    goal = np.zeros(3)
    achieved = np.array([[0.0, 0.0, 0.049], [0.0, 0.0, 0.051]])
    np.testing.assert_array_equal(env.compute_reward(achieved, goal, {}), [1.0, 0.0])
    assert env.compute_reward(achieved[0], goal, {}) == 1.0


def test_model_and_data_are_exposed():
    env = gym.make("tsrl/UR5eReach-v0").unwrapped
    env.reset(seed=0)
    assert env.model.nq == 6 and env.data.qpos.shape == (6,)
    assert env.n_substeps == 20 and env.model.opt.timestep == 0.002


def test_rgb_array_rendering_shows_the_scene():
    env = gym.make("tsrl/UR5ePickPlace-v0", render_mode="rgb_array", width=160, height=120)
    env.reset(seed=0)
    image = env.render()
    env.close()
    assert image.shape == (120, 160, 3) and image.std() > 10


def test_human_rendering_without_a_display_says_so(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    env = gym.make("tsrl/UR5eReach-v0", render_mode="human").unwrapped
    env.reset(seed=0)
    with pytest.raises(tsrl.exceptions.InvalidConfig, match="needs a display"):
        env.render()
