"""FeatureHerReplayBuffer: relabelled transitions agree with env.relabel of the stored ones."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv
from training_helpers import fill_with_random_episodes

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import FeatureHerReplayBuffer

ENV_ID = "tsrl/UR5eReach-v0"
EPISODES = 4


def filled_buffer(relabel_features: bool) -> tuple[FeatureHerReplayBuffer, DummyVecEnv]:
    """A buffer holding EPISODES random-action episodes of the reach env (fs1: goal-dependent features)."""
    venv = DummyVecEnv([lambda: gym.make(ENV_ID, obs="fs1")])
    buffer = FeatureHerReplayBuffer(
        1000, venv.observation_space, venv.action_space, venv, device="cpu", relabel_features=relabel_features
    )
    fill_with_random_episodes(buffer, venv, EPISODES)
    return buffer, venv


def stored_index(buffer: FeatureHerReplayBuffer, action: np.ndarray) -> int:
    """Row of the stored transition with this action (random continuous actions are unique)."""
    rows = np.flatnonzero(np.all(np.isclose(buffer.actions[: buffer.pos, 0], action, atol=1e-6), axis=1))
    assert len(rows) == 1
    return int(rows[0])


def test_relabelled_batch_agrees_with_env_relabel():
    buffer, venv = filled_buffer(relabel_features=True)
    env = venv.envs[0].unwrapped
    np.random.seed(1)
    batch = buffer.sample(200)
    n_real = 200 - int(buffer.her_ratio * 200)  # SB3 puts the real transitions first, then the relabelled
    obs = {k: v.numpy() for k, v in batch.observations.items()}
    next_obs = {k: v.numpy() for k, v in batch.next_observations.items()}
    actions = batch.actions.numpy()
    changed = 0
    for i in range(200):
        row = stored_index(buffer, actions[i])
        stored = {k: v[row, 0] for k, v in buffer.observations.items()}
        stored_next = {k: v[row, 0] for k, v in buffer.next_observations.items()}
        goal = obs["desired_goal"][i]
        if i >= n_real:  # relabelled: what the env would have emitted with the goal at `goal`
            expected, expected_next = env.relabel(stored, goal), env.relabel(stored_next, goal)
            changed += not np.allclose(goal, stored["desired_goal"])
        else:  # real transitions are returned as stored
            expected, expected_next = stored, stored_next
        for key in obs:
            np.testing.assert_allclose(obs[key][i], expected[key], rtol=0, atol=1e-12)
            np.testing.assert_allclose(next_obs[key][i], expected_next[key], rtol=0, atol=1e-12)
        reward = env.compute_reward(next_obs["achieved_goal"][i], goal, {})
        assert batch.rewards.numpy()[i, 0] == reward
    assert changed > (200 - n_real) // 2  # most relabelled goals differ from the stored one


def test_plain_her_leaves_goal_dependent_features_stale():
    """The bug the feature-aware buffer fixes: SB3's HER keeps positionDiff(tcp, target) of the old goal."""
    buffer, venv = filled_buffer(relabel_features=False)
    env = venv.envs[0].unwrapped
    np.random.seed(1)
    batch = buffer.sample(200)
    n_real = 200 - int(buffer.her_ratio * 200)
    obs = {k: v.numpy()[n_real:] for k, v in batch.observations.items()}
    diff = env.observation_structure["positionDiff(tcp, target)"]
    stale = ~np.isclose(obs["observation"][:, diff], obs["achieved_goal"] - obs["desired_goal"]).all(axis=1)
    assert stale.mean() > 0.5


def test_buffer_pickles_compactly_and_grows():
    import pickle

    buffer, venv = filled_buffer(relabel_features=True)
    data = pickle.dumps(buffer)
    assert len(data) < 200_000  # 200 transitions, not 1000 rows
    restored = pickle.loads(data)
    restored.set_env(venv)
    assert restored.buffer_size == 1000 and restored.pos == buffer.pos
    for key in buffer.observations:
        np.testing.assert_array_equal(restored.observations[key], buffer.observations[key])
    np.testing.assert_array_equal(restored.ep_length, buffer.ep_length)
    restored.grow(2000)
    assert restored.buffer_size == 2000 and restored.observations["observation"].shape[0] == 2000
    np.random.seed(0)
    assert restored.sample(32).observations["observation"].shape == (32, 15)


def test_feature_relabel_needs_an_env_with_relabel():
    from stable_baselines3.common.env_util import make_vec_env

    from tsrl.exceptions import InvalidConfig

    venv = make_vec_env("Pendulum-v1")
    with pytest.raises(InvalidConfig, match="plain"):
        FeatureHerReplayBuffer(
            100, gym.spaces.Dict({"observation": venv.observation_space}), venv.action_space, venv
        )
