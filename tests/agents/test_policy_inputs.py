"""AgentConfig.policy_inputs: the networks see only the selected keys of the observation dict, HER and
normalisation still use all of them, and the default is stable-baselines3's own extractor, bit for bit."""

from __future__ import annotations

import pytest
import torch as th
from stable_baselines3.common.torch_layers import CombinedExtractor
from training_helpers import tiny

from tsrl.agents import AgentConfig, TrainConfig, factory
from tsrl.agents.factory import make_agent, make_vec_env
from tsrl.exceptions import InvalidConfig

FS1_DIM = 15  # paper Table I
GOAL_DIM = ACTION_DIM = 3


def test_networks_see_the_selected_keys_of_a_relabelled_sample():
    cfg = tiny(policy_inputs=("observation", "desired_goal"))
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(total_timesteps=100)  # random steps only: two episodes in the buffer, no update
    assert model.actor.features_extractor.features_dim == FS1_DIM + GOAL_DIM
    assert model.actor.mu[0].in_features == FS1_DIM + GOAL_DIM
    assert model.critic.qf0[0].in_features == FS1_DIM + GOAL_DIM + ACTION_DIM

    batch = model.replay_buffer.sample(64, env=model._vec_normalize_env).observations  # 80% relabelled
    assert set(batch) == {"observation", "achieved_goal", "desired_goal"}  # HER still fills every key
    features = model.actor.features_extractor(batch)
    th.testing.assert_close(features, th.cat([batch["desired_goal"], batch["observation"]], dim=1))

    with th.no_grad():
        action = model.actor(batch)
        moved_tcp = dict(batch, achieved_goal=batch["achieved_goal"] + 1.0)
        moved_goal = dict(batch, desired_goal=batch["desired_goal"] + 1.0)
        th.testing.assert_close(model.actor(moved_tcp), action)  # achieved_goal is not an input
        assert not th.allclose(model.actor(moved_goal), action)


class _Sb3Default(CombinedExtractor):
    """What make_agent built before policy_inputs existed: SB3's extractor over the whole dict."""

    def __init__(self, observation_space, keys):
        super().__init__(observation_space)


def _first_update(cfg: TrainConfig) -> dict[str, th.Tensor]:
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(total_timesteps=200)  # 100 random steps, then one update of 10 gradient steps
    return {k: v.clone() for k, v in model.policy.state_dict().items()}


def test_default_inputs_give_the_same_first_update_as_sb3s_extractor(monkeypatch):
    cfg = tiny()
    assert cfg.agent.policy_inputs == ("observation", "achieved_goal", "desired_goal")
    ours = _first_update(cfg)
    monkeypatch.setattr(factory, "PolicyInputs", _Sb3Default)
    before = _first_update(cfg)
    assert ours.keys() == before.keys()
    changed = [k for k in ours if not th.equal(ours[k], before[k])]
    assert not changed
    initial = make_agent(cfg, make_vec_env(cfg)).policy.state_dict()
    assert any(not th.equal(initial[k], ours[k]) for k in ours)  # the update did change the networks


@pytest.mark.parametrize(
    ("inputs", "message"),
    [
        (
            ("observation", "goal"),
            "unknown policy input 'goal'; accepted: observation, achieved_goal, desired_goal",
        ),
        ((), "at least one"),
        (("observation", "observation"), "at most once"),
    ],
)
def test_bad_policy_inputs_name_the_accepted_keys(inputs, message):
    with pytest.raises(InvalidConfig, match=message):
        AgentConfig(policy_inputs=inputs)
