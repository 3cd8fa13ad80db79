"""The fast learner's parts (issue 55): its actor starts as behaviour cloning of the demonstrations;
its actor loss scales the -Q gradient by alpha / mean|Q(s, pi(s))| (TD3+BC's anchor) after a warm-up
in which the actor only clones; the preset resolves to twin critics, gamma 0.98, no random steps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import configure
from training_helpers import fill_with_random_episodes, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.action_penalty import actor_action
from tsrl.agents.bc import DemoBatches
from tsrl.agents.config import DemoConfig, HerConfig, InvalidConfig
from tsrl.agents.demo_files import load_demos
from tsrl.agents.demos import BCLoss, DemoReplayBuffer, first_q

REACH = "tsrl/UR5eReach-v0"


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def fast(path: Path, **agent: object) -> TrainConfig:
    demos = DemoConfig(path=str(path))
    return TrainConfig(
        env_id=REACH, obs="fs1", agent=AgentConfig(learner="fast", batch_size=64, demos=demos, **agent)
    )


def test_the_fast_preset_resolves_and_given_options_win(reach_demos):
    a = fast(reach_demos).agent
    assert (a.algo, a.gamma, a.learning_starts, a.action_noise) == ("td3", 0.98, 0, 0.1)
    assert (a.demos.bc_anchor, a.demos.bc_anchor_warmup, a.layer_norm) == (0.25, 2_500, "critic")
    assert a.reward_scale == 0.5 and fast(reach_demos).env_kwargs["reward_scale"] == 0.5
    given = fast(reach_demos, algo="ddpg", gamma=0.95, reward_scale=1.0)
    assert (given.agent.algo, given.agent.gamma, given.agent.reward_scale) == ("ddpg", 0.95, 1.0)
    assert "reward_scale" not in given.env_kwargs  # the task's reward: gym.make as before
    paper = AgentConfig()
    assert (paper.algo, paper.gamma, paper.learning_starts, paper.action_noise) == ("ddpg", 0.95, 500, 0.2)
    assert paper.demos.bc_anchor is None and paper.reward_scale == 1.0


def test_the_fast_preset_bounds_its_critic_where_the_bound_fits(reach_demos):
    assert fast(reach_demos).agent.return_bound == 1.0  # pre-registration 17 of the study
    assert fast(reach_demos, return_bound=0.0).agent.return_bound == 0.0  # given wins
    assert AgentConfig(learner="fast").return_bound == 1.0  # a file given later keeps it (experiments)
    unfit = fast(reach_demos, her=HerConfig(relabel="plain")).agent  # no feature HER: no returns
    assert unfit.return_bound == 0.0 and fast(reach_demos, gamma=1.0).agent.return_bound == 0.0
    assert AgentConfig(demos=DemoConfig(path=str(reach_demos))).return_bound == 0.0  # paper: none
    with pytest.raises(InvalidConfig, match="return_bound 1.0 bounds"):
        fast(reach_demos, her=HerConfig(relabel="plain"), return_bound=1.0)  # asked for: one line


def test_demonstrations_learn_under_the_runs_reward_scale_and_their_file_keeps_the_tasks(reach_demos):
    from tsrl.agents.demo_files import demo_record
    from tsrl.agents.demos import load_run_demos

    cfg = fast(reach_demos)
    assert demo_record(cfg) is not None  # the file's rewards are checked against the task's reward
    venv = make_vec_env(cfg)
    learned = load_run_demos(cfg.agent.demos, venv, None)
    stored = load_demos(reach_demos)
    env = venv.envs[0].unwrapped  # type: ignore[attr-defined]
    g = stored.achieved_goal.shape[2]
    after = stored.achieved_goal[:, 1:].reshape(-1, g), stored.desired_goal[:, 1:].reshape(-1, g)
    distance = np.linalg.norm(after[0] - after[1], axis=1).reshape(stored.rewards.shape)
    np.testing.assert_array_equal(stored.rewards, distance < 0.05)  # the task's (UR5eReach: 5 cm)
    np.testing.assert_array_equal(learned.rewards, distance < 0.025)  # the run's: half of it
    assert learned.rewards.dtype == stored.rewards.dtype
    assert ((distance >= 0.025) & (distance < 0.05)).any()  # steps rewarded only by the task: can fail
    assert env.compute_reward(*after, None).reshape(stored.rewards.shape).tolist() == learned.rewards.tolist()


def test_the_fast_actor_starts_as_behaviour_cloning_of_the_demonstrations(reach_demos):
    cfg = fast(reach_demos, bc_steps=1500)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    demos = load_demos(reach_demos)
    batches = DemoBatches(demos, venv)  # the normaliser already holds the demonstration states
    with th.no_grad():
        cloned = actor_action(model, batches.obs)
        target = model.actor_target(batches.obs)
    untrained = make_agent(fast(reach_demos, bc_steps=0), make_vec_env(cfg))
    with th.no_grad():
        before = actor_action(untrained, batches.obs)
    error = ((cloned - batches.actions) ** 2).mean().item()
    assert error < 0.2 * ((before - batches.actions) ** 2).mean().item()
    assert th.equal(cloned, target)  # the target actor copied from the cloned one


@pytest.mark.parametrize(
    ("env_steps", "ramp"), [(0, 0.0), (2_000, 0.0), (3_750, 0.5), (5_000, 1.0), (9_000, 1.0)]
)
def test_the_anchor_scales_the_q_gradient_after_its_warmup(reach_demos, env_steps, ramp):
    cfg = fast(reach_demos, bc_steps=0)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    model.set_logger(configure(None, []))
    buffer = model.replay_buffer
    assert isinstance(buffer, DemoReplayBuffer)
    fill_with_random_episodes(buffer, venv, 2)
    batch = buffer.sample(64, venv)
    optimizer = model.actor.optimizer
    optimizer.zero_grad()
    (-first_q(model.critic, batch.observations, model.actor(batch.observations)).mean()).backward()
    raw = [p.grad.clone() for p in model.actor.parameters()]
    with th.no_grad():
        mean_abs_q = first_q(model.critic, batch.observations, model.actor(batch.observations)).abs().mean()
    model.num_timesteps = env_steps
    BCLoss(model, weight=0.0, q_filter=True, anchor=2.5, warmup=2_500)(optimizer, (), {})
    scale = ramp * 2.5 / mean_abs_q.item()
    for before, param in zip(raw, model.actor.parameters(), strict=True):
        np.testing.assert_allclose(param.grad.numpy(), scale * before.numpy(), rtol=1e-5, atol=1e-12)
    assert any(g.abs().max() > 0 for g in raw)  # a gradient to scale: the comparison can fail


def test_the_anchored_bc_term_is_unfiltered(reach_demos):
    loss = BCLoss(object(), weight=1.0, q_filter=True, anchor=2.5)  # type: ignore[arg-type]
    assert not loss.q_filter
    assert BCLoss(object(), weight=1.0, q_filter=True).q_filter  # type: ignore[arg-type]


def test_a_run_folder_from_before_the_reward_scale_loads_with_the_tasks_reward(reach_demos, tmp_path):
    import json

    from tsrl.agents.run_folder import CONFIG_FILE, load_config, write_json_atomic

    data = fast(reach_demos).to_dict()
    assert data["agent"]["reward_scale"] == 0.5  # a new run names what it uses
    write_json_atomic(tmp_path / CONFIG_FILE, data)
    assert load_config(tmp_path).agent.reward_scale == 0.5
    del data["agent"]["reward_scale"]  # a fast run's folder written before the field: the task's reward
    (tmp_path / CONFIG_FILE).write_text(json.dumps(data))
    old = load_config(tmp_path)
    assert old.agent.reward_scale == 1.0 and "reward_scale" not in old.env_kwargs


def test_a_run_folder_from_before_the_return_bound_loads_without_it(reach_demos, tmp_path):
    import json

    from tsrl.agents.run_folder import CONFIG_FILE, load_config

    data = fast(reach_demos).to_dict()
    assert data["agent"]["return_bound"] == 1.0  # a new run names what it uses
    del data["agent"]["return_bound"]  # a fast run's folder written before the field: no bound
    (tmp_path / CONFIG_FILE).write_text(json.dumps(data))
    assert load_config(tmp_path).agent.return_bound == 0.0
