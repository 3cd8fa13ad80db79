"""The action penalty (AgentConfig.action_l2, tsrl.agents.action_penalty): off by default; on, the
actor's step follows grad(actor loss + weight * mean squared action) and nothing else changes; it
survives a resume; bad weights are one line."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th
from training_helpers import scalar_steps, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, make_agent, make_vec_env, resume, train
from tsrl.agents.action_penalty import ActionPenalty
from tsrl.exceptions import InvalidConfig


def _model_with_stored_steps(**agent: object):
    """A tiny reach DDPG agent after its 100 random steps and one episode more (no update yet but
    those of the one `learn` call), the same for the same config."""
    cfg = tiny(**agent)
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(100)
    return model


def _state(module: th.nn.Module) -> dict[str, th.Tensor]:
    return {k: v.clone() for k, v in module.state_dict().items()}


def test_the_default_has_no_penalty_and_the_same_run():
    assert AgentConfig().action_l2 == 0.0
    assert tiny().run_name == tiny(action_l2=0.0).run_name
    assert tiny(action_l2=1.0).run_name.endswith("__s0__action-l2-1")
    default, explicit = _model_with_stored_steps(), _model_with_stored_steps(action_l2=0.0)
    for model in (default, explicit):
        np.random.seed(1)
        model.train(gradient_steps=5, batch_size=64)
    for key, value in _state(default.policy).items():
        assert th.equal(explicit.policy.state_dict()[key], value)


def test_the_penalty_adds_its_gradient_to_the_actor_loss():
    weight = 0.7
    model = _model_with_stored_steps()
    batch = model.replay_buffer.sample(64, model.get_vec_normalize_env())
    assert model.replay_buffer.last_batch is batch
    actor, critic = model.actor, model.critic

    def actor_grads(extra: bool) -> list[th.Tensor]:
        actor.optimizer.zero_grad()
        (-critic.q1_forward(batch.observations, actor(batch.observations)).mean()).backward()
        if extra:  # the hook, as the optimizer's step would call it
            ActionPenalty(model, weight)(actor.optimizer, (), {})
        else:  # independently: the penalty's sum written out, in one backward with the actor loss
            actor.optimizer.zero_grad()
            pi = actor(batch.observations)
            q = critic.q1_forward(batch.observations, pi)
            (-q.mean() + weight * (pi * pi).sum() / pi.numel()).backward()
        return [p.grad.clone() for p in actor.parameters()]

    with_hook, by_hand = actor_grads(True), actor_grads(False)
    for a, b in zip(with_hook, by_hand, strict=True):
        assert th.allclose(a, b, atol=1e-6)
    assert "train/action_l2" in model.logger.name_to_value


def test_the_penalty_changes_only_the_actors_step():
    plain, penalised = _model_with_stored_steps(), _model_with_stored_steps(action_l2=5.0)
    for key, value in _state(plain.policy).items():
        assert th.equal(penalised.policy.state_dict()[key], value)  # the same start
    for model in (plain, penalised):
        np.random.seed(1)
        model.train(gradient_steps=1, batch_size=64)  # DDPG: the critic's step, then the actor's
    for key, value in plain.critic.state_dict().items():
        assert th.equal(penalised.critic.state_dict()[key], value)
    assert any(not th.equal(penalised.actor.state_dict()[k], v) for k, v in plain.actor.state_dict().items())


def test_a_large_penalty_shrinks_the_actions():
    plain, penalised = _model_with_stored_steps(), _model_with_stored_steps(action_l2=20.0)
    for model in (plain, penalised):
        np.random.seed(1)
        model.train(gradient_steps=100, batch_size=64)
    batch = plain.replay_buffer.sample(256, plain.get_vec_normalize_env())
    with th.no_grad():
        size = [float((m.actor(batch.observations) ** 2).mean()) for m in (plain, penalised)]
    assert size[1] < 0.5 * size[0]


def test_a_resumed_run_keeps_the_penalty(tmp_path):
    run_dir = train(tiny(total=200, action_l2=1.0), tmp_path, progress_bar=False)
    resume(run_dir, total_timesteps=400, progress_bar=False)
    steps = scalar_steps(run_dir, "train/action_l2")
    assert max(steps) == 400


@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf")])
def test_a_bad_weight_is_one_line(weight):
    with pytest.raises(InvalidConfig, match="action_l2") as err:
        AgentConfig(action_l2=weight)
    assert "\n" not in str(err.value)
