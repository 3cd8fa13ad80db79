"""A critic ensemble and the actor climbing its lowest head (AgentConfig.critics, AgentConfig.actor_value;
IBRL's critics): N heads where asked, the same draws as before for the default; LowestHeadCritic's value
is the lowest head (an independent computation) and is what TD3's actor loss climbs; the fast learner's
choice and TD target take the smallest of N heads; a saved model keeps both; bad values are one line
(exit 2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch as th
from cli_runner import TINY, run_tsrl
from stable_baselines3 import TD3
from training_helpers import fast_reach, random_obs_batch, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.learners import LowestHeadCritic
from tsrl.agents.reference import choose
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def _td3(seed: int = 0, **agent: object) -> TD3:
    cfg = TrainConfig(
        env_id=REACH,
        obs="fs1",
        total_timesteps=400,
        seed=seed,
        agent=AgentConfig(algo="td3", **agent),  # type: ignore[arg-type]
    )
    model = make_agent(cfg, make_vec_env(cfg))
    assert isinstance(model, TD3)
    return model


def test_the_default_is_twin_heads_and_the_same_networks_as_before():
    plain, explicit = _td3(), _td3(critics=2, actor_value="first")
    assert len(plain.critic.q_networks) == 2 and type(plain.critic).__name__ == "ContinuousCritic"
    assert plain.policy_kwargs.keys() == explicit.policy_kwargs.keys()  # the defaults add no saved kwarg
    for a, b in zip(plain.policy.parameters(), explicit.policy.parameters(), strict=True):
        assert th.equal(a, b)


def test_the_lowest_head_is_the_actors_value_and_the_networks_keep_their_draws():
    first, lowest = _td3(), _td3(actor_value="lowest")
    for critic in (lowest.critic, lowest.critic_target):
        assert isinstance(critic, LowestHeadCritic)
    for a, b in zip(first.policy.parameters(), lowest.policy.parameters(), strict=True):
        assert th.equal(a, b)  # only the value the actor climbs differs
    obs = random_obs_batch(lowest, 32, seed=1)
    actions = th.rand(32, lowest.action_space.shape[0]) * 2 - 1  # type: ignore[index]
    with th.no_grad():
        features = th.cat([obs[k] for k in sorted(obs)], dim=1)  # the extractor's order: sorted keys
        by_hand = th.cat([q(th.cat([features, actions], dim=1)) for q in lowest.critic.q_networks], dim=1)
        np.testing.assert_allclose(
            lowest.critic.q1_forward(obs, actions).numpy(),
            by_hand.min(dim=1, keepdim=True).values.numpy(),
            atol=1e-6,
        )
        np.testing.assert_allclose(
            first.critic.q1_forward(obs, actions).numpy(), by_hand[:, :1].numpy(), atol=1e-6
        )
        assert (by_hand[:, 0] > by_hand[:, 1]).any()  # rows where the first head is not the lowest


def test_tds_actor_loss_climbs_the_lowest_head():
    model = _td3(actor_value="lowest", learning_starts=0)
    model.learn(200)  # a replay to train on
    seen: list[th.Tensor] = []
    q1_forward = model.critic.q1_forward

    def spy(obs, actions):  # records what the actor loss is made of
        value = q1_forward(obs, actions)
        seen.append(th.cat(model.critic(obs, actions), dim=1).min(dim=1, keepdim=True).values - value)
        return value

    model.critic.q1_forward = spy  # type: ignore[method-assign]
    model.train(gradient_steps=2, batch_size=16)  # TD3 updates its actor on every second step
    assert seen and all(th.equal(gap, th.zeros_like(gap)) for gap in seen)


def test_further_heads_leave_the_other_networks_draws_and_differ_by_seed(reach_demos):
    twin, five, five_other_seed = _td3(), _td3(critics=5), _td3(seed=1, critics=5)
    assert len(five.critic.q_networks) == 5 and five.critic.n_critics == 5
    for a, b in zip(twin.actor.parameters(), five.actor.parameters(), strict=True):
        assert th.equal(a, b)
    for head in (0, 1):
        for a, b in zip(
            twin.critic.q_networks[head].parameters(), five.critic.q_networks[head].parameters(), strict=True
        ):
            assert th.equal(a, b)
    for net in (five, five_other_seed):  # the target starts as the critic, head for head
        for a, b in zip(net.critic.parameters(), net.critic_target.parameters(), strict=True):
            assert th.equal(a, b)
    first_weight = [next(q.parameters()) for q in five.critic.q_networks]
    assert not any(th.equal(first_weight[i], first_weight[j]) for i in range(5) for j in range(i + 1, 5))
    assert not th.equal(first_weight[2], next(five_other_seed.critic.q_networks[2].parameters()))
    models = {}
    for heads in (2, 5):  # the fast learner's clone too
        cfg = fast_reach(reach_demos, critics=heads)
        models[heads] = make_agent(cfg, make_vec_env(cfg))
    for a, b in zip(
        models[2].policy.reference.parameters(), models[5].policy.reference.parameters(), strict=True
    ):
        assert th.equal(a, b)


def test_n_critics_feed_the_choice_and_the_td_target(reach_demos):
    cfg = fast_reach(reach_demos, critics=5, actor_value="lowest")
    model = make_agent(cfg, make_vec_env(cfg))
    policy = model.policy
    assert len(policy.critic.q_networks) == 5 and len(policy.critic_target.q_networks) == 5
    assert cfg.run_name.endswith("__critics-5__actor-lowest")
    with th.no_grad():  # an actor away from its clone, so the choice has something to choose
        for p in policy.actor.parameters():
            p.add_(0.3 * th.randn_like(p))
    obs = random_obs_batch(model, 64, seed=2)
    with th.no_grad():
        actor, clone = policy.actor(obs), policy.reference(obs)
        low_actor = th.cat(policy.critic(obs, actor), dim=1).min(dim=1).values
        low_clone = th.cat(policy.critic(obs, clone), dim=1).min(dim=1).values
        expected = th.where((low_clone > low_actor)[:, None], clone, actor)
        assert th.equal(choose(policy.critic, obs, actor, clone), expected)
        policy.choice_acts.fill_(True)
        assert th.equal(policy._predict(obs), expected)
        target_actor, low_t = model.actor_target.actor(obs), {}
        for name, a in (("actor", target_actor), ("clone", clone)):
            low_t[name] = th.cat(policy.critic_target(obs, a), dim=1).min(dim=1).values
        chosen_t = th.where((low_t["clone"] > low_t["actor"])[:, None], clone, target_actor)
        assert th.equal(model.actor_target(obs), chosen_t)


def test_a_saved_model_keeps_its_heads_and_its_actors_value(reach_demos, tmp_path):
    cfg = fast_reach(reach_demos, critics=3, actor_value="lowest")
    model = make_agent(cfg, make_vec_env(cfg))
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert isinstance(loaded.critic, LowestHeadCritic) and len(loaded.critic.q_networks) == 3
    obs = random_obs_batch(model, 8, seed=3)
    actions = th.zeros(8, model.action_space.shape[0])  # type: ignore[index]
    with th.no_grad():
        assert th.equal(loaded.critic.q1_forward(obs, actions), model.critic.q1_forward(obs, actions))


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        ({"critics": 0}, r"^critics must be an integer >= 1; got 0"),
        ({"critics": 2.5}, r"^critics must be an integer >= 1; got 2.5"),
        ({"critics": 4}, r"^critics 4 sets the critic heads of td3, but algo is 'ddpg'; accepted"),
        ({"actor_value": "mean"}, r"^unknown actor_value 'mean'; accepted: first, lowest$"),
        ({"actor_value": "lowest", "algo": "sac"}, r"^actor_value 'lowest' sets the value TD3's actor climbs, but algo is 'sac'"),
    ],
)  # fmt: skip
def test_bad_values_are_one_line(agent, message):
    with pytest.raises(InvalidConfig, match=message) as err:
        AgentConfig(**agent)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_head_count_with_exit_2(tmp_path):
    result = run_tsrl("train", *TINY, "--algo", "td3", "--critics", "0", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "critics must be an integer >= 1; got 0" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
