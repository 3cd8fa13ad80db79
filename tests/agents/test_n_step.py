"""N-step targets (AgentConfig.n_step; tsrl.agents.her): each sampled row's reward, next observation,
done and discount against an independent computation from the stored episodes (real and relabelled
rows, rows near an episode's end); the default keeps one-step rows and the saved kwargs as before;
TD3 trains on the discounts, demonstration rows included; the run name says it; bad values are one
line (exit 2)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from cli_runner import TINY, run_tsrl
from stable_baselines3.common.vec_env import DummyVecEnv
from training_helpers import saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.config import DemoConfig
from tsrl.agents.her import FeatureHerReplayBuffer
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"
GAMMA = 0.9


def filled_buffer(n_step: int, episodes: int = 4) -> tuple[FeatureHerReplayBuffer, gym.Env, list[dict]]:
    """A feature HER buffer of `episodes` random-action reach episodes (25 steps each), its env, and the
    raw steps stored, in order: {"obs": observation dict, "action", "next": next observation dict}."""
    venv = DummyVecEnv([lambda: gym.make(REACH, obs="fs1", max_episode_steps=25)])
    buffer = FeatureHerReplayBuffer(
        episodes * 25, venv.observation_space, venv.action_space, venv, n_step=n_step, n_step_gamma=GAMMA
    )  # type: ignore[arg-type]
    venv.seed(3)
    rng = np.random.default_rng(0)
    obs, steps = venv.reset(), []
    for _ in range(episodes * 25):
        action = rng.uniform(-1, 1, size=(1, *venv.action_space.shape))  # type: ignore[misc]
        next_obs, reward, done, infos = venv.step(action)
        stored_next = infos[0]["terminal_observation"] if done[0] else next_obs
        stored_next = {k: np.asarray(v).reshape(1, -1) for k, v in stored_next.items()}
        buffer.add(obs, stored_next, action, reward, done, infos)  # type: ignore[arg-type]
        steps.append(
            {
                "obs": {k: v[0].copy() for k, v in obs.items()},
                "action": action[0],
                "next": {k: v[0].copy() for k, v in stored_next.items()},
            }
        )
        obs = next_obs
    return buffer, venv.envs[0], steps


def expected_row(env: gym.Env, steps: list[dict], index: int, goal: np.ndarray, n: int) -> dict:
    """The N-step row of stored step `index` under `goal`, computed step by step (episodes of 25)."""
    left = 25 - index % 25
    k = min(n, left)
    unwrapped = env.unwrapped
    rewards = [
        float(unwrapped.compute_reward(steps[index + j]["next"]["achieved_goal"], goal, {})) for j in range(k)
    ]  # type: ignore[attr-defined]
    next_obs = unwrapped.relabel(steps[index + k - 1]["next"], goal)  # type: ignore[attr-defined]
    return {
        "reward": sum(GAMMA**j * r for j, r in enumerate(rewards)),
        "next": next_obs,
        "discount": GAMMA**k,
    }


def test_every_row_is_its_n_step_transition_real_and_relabelled():
    n = 3
    buffer, env, steps = filled_buffer(n)
    np.random.seed(0)
    batch = buffer.sample(256)
    actions = np.stack([s["action"] for s in steps])
    assert batch.discounts is not None
    near_end = relabelled = 0
    for row in range(256):
        goal = batch.observations["desired_goal"][row].numpy().astype(np.float64)
        # the stored step: its action (random, so one of a kind)
        candidates = np.flatnonzero(np.all(np.isclose(actions, batch.actions[row].numpy()), axis=1))
        assert len(candidates) == 1
        index = int(candidates[0])
        relabelled += not np.allclose(goal, steps[index]["obs"]["desired_goal"])
        want = expected_row(env, steps, index, goal, n)
        near_end += 25 - index % 25 < n
        assert batch.rewards[row, 0].item() == pytest.approx(want["reward"], abs=1e-5)
        assert batch.discounts[row, 0].item() == pytest.approx(want["discount"], rel=1e-6)
        assert batch.dones[row, 0].item() == 0.0  # time-limit ends bootstrap
        for key, value in want["next"].items():
            np.testing.assert_allclose(batch.next_observations[key][row].numpy(), value, atol=1e-5)
    assert relabelled > 100 and near_end > 0  # both kinds of row, and rows cut by the episode's end


def test_one_step_rows_are_as_before():
    buffer, _, _ = filled_buffer(1)
    np.random.seed(0)
    batch = buffer.sample(64)
    assert batch.discounts is None and buffer.n_step == 1


def test_td3_trains_on_n_step_discounts_with_demonstrations(tmp_path_factory):
    demos = saved_reach_demos(tmp_path_factory, 4)
    agent = AgentConfig(
        algo="td3", n_step=3, demos=DemoConfig(path=str(demos)), gradient_steps=5, learning_starts=100
    )
    cfg = TrainConfig(env_id=REACH, obs="fs1", total_timesteps=300, seed=0, agent=agent)
    assert cfg.run_name.endswith("__demos__n-step-3")
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(300)
    batch = model.replay_buffer.last_batch  # type: ignore[union-attr]
    assert batch is not None and batch.discounts is not None and len(batch.discounts) == agent.batch_size
    allowed = np.array([agent.gamma**k for k in (1, 2, 3)])
    assert np.isclose(batch.discounts.numpy(), allowed[None, :]).any(axis=1).all()  # (n, 1) against the 3
    assert (batch.discounts[-round(agent.demos.batch_share * agent.batch_size) :] > 0).all()  # demo rows too


def test_the_default_adds_no_buffer_kwarg():
    cfg = TrainConfig(env_id=REACH, obs="fs1", total_timesteps=300, agent=AgentConfig(algo="td3"))
    model = make_agent(cfg, make_vec_env(cfg))
    assert "n_step" not in model.replay_buffer_kwargs and cfg.run_name.endswith("__td3__s0")


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        ({"n_step": 0}, r"^n_step must be an integer >= 1; got 0"),
        ({"n_step": 3, "algo": "bc"}, r"^n_step 3 makes the critic's target an N-step return .* algo 'bc'"),
        ({"n_step": 3, "her": {"relabel": "plain"}}, r"^n_step 3 .* her relabel 'plain'.*; accepted with these: 1$"),
    ],
)  # fmt: skip
def test_bad_values_are_one_line(agent, message):
    if "her" in agent:
        from tsrl.agents.config import HerConfig

        agent = agent | {"her": HerConfig(relabel="plain")}
    with pytest.raises(InvalidConfig, match=message) as err:
        AgentConfig(**agent)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_n_step_with_exit_2(tmp_path: Path):
    result = run_tsrl("train", *TINY, "--algo", "td3", "--n-step", "0", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "n_step must be an integer >= 1; got 0" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_tensor_batch_is_float32():
    buffer, _, _ = filled_buffer(2, episodes=2)
    batch = buffer.sample(32)
    for tensor in (batch.rewards, batch.dones, batch.discounts):
        assert tensor is not None and tensor.dtype == th.float32


def test_a_saved_buffer_keeps_its_n_step(tmp_path: Path):
    cfg = TrainConfig(env_id=REACH, obs="fs1", total_timesteps=300, agent=AgentConfig(algo="td3", n_step=4))
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(100)
    model.save_replay_buffer(tmp_path / "buffer.pkl")
    again = make_agent(dataclasses.replace(cfg, agent=AgentConfig(algo="td3")), make_vec_env(cfg))
    again.load_replay_buffer(tmp_path / "buffer.pkl")
    buffer = again.replay_buffer
    assert (
        isinstance(buffer, FeatureHerReplayBuffer)
        and buffer.n_step == 4
        and buffer.n_step_gamma == cfg.agent.gamma
    )
