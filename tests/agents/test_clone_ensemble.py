"""The fast learner's reference as the mean action of several clones (AgentConfig.clones,
tsrl.agents.reference.CloneEnsemble): the first clone and the actor are those of the run without it,
the others come from their own draws and differ; each is a BC fit of the demonstrations; the reference
is their mean action in acting, the choice and the TD target; a saved model keeps them; bad values are
one line (exit 2)."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
import torch as th
import torch.nn.functional as F
from cli_runner import TINY, run_tsrl
from stable_baselines3 import TD3
from stable_baselines3.common.vec_env import VecNormalize
from training_helpers import fast_reach, random_obs_batch, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.bc import DemoBatches
from tsrl.agents.demo_files import load_demos
from tsrl.agents.reference import CloneEnsemble, ReferenceTD3Policy, choose
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"
C = 3


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def fast(path: Path, seed: int = 0, **agent: object) -> TrainConfig:
    return fast_reach(path, seed=seed, **({"bc_steps": 300} | agent))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def one_and_three(reach_demos):
    models = {}
    for clones in (1, C):
        cfg = fast(reach_demos, clones=clones)
        models[clones] = make_agent(cfg, make_vec_env(cfg))
    return models


def _same(a: th.nn.Module, b: th.nn.Module) -> bool:
    return all(th.equal(x, y) for x, y in zip(a.parameters(), b.parameters(), strict=True))


def test_the_first_clone_and_the_actor_are_the_runs_without_it_the_others_differ(one_and_three):
    one, three = one_and_three[1].policy, one_and_three[C].policy
    assert isinstance(three.reference, CloneEnsemble) and len(three.reference.members) == C
    assert not isinstance(one.reference, CloneEnsemble)
    assert _same(one.reference, three.reference.members[0])
    assert _same(one.actor, three.actor) and _same(one.critic, three.critic)
    assert _same(three.actor.mu, three.reference.members[0].mu)  # the actor starts as the first clone
    firsts = [next(m.parameters()) for m in three.reference.members]
    assert not any(th.equal(firsts[i], firsts[j]) for i in range(C) for j in range(i + 1, C))
    assert not any(p.requires_grad for p in three.reference.parameters())


def test_each_clone_fits_the_demonstrations_and_the_reference_is_their_mean(one_and_three, reach_demos):
    model = one_and_three[C]
    policy = model.policy
    normalizer = model.get_env()
    assert isinstance(normalizer, VecNormalize)
    batches = DemoBatches(load_demos(reach_demos), normalizer)
    obs = random_obs_batch(model, 64, seed=1)
    with th.no_grad():
        members = [m(obs) for m in policy.reference.members]
        np.testing.assert_allclose(
            policy.reference(obs).numpy(), th.stack(members).mean(dim=0).numpy(), rtol=0, atol=1e-7
        )
        states, actions = batches.obs, batches.actions
        constant = F.mse_loss(actions.mean(dim=0).expand_as(actions), actions)  # the best constant action
        for member in policy.reference.members:
            assert F.mse_loss(member(states), actions) < 0.5 * constant


def test_acting_and_the_target_choose_against_the_mean_action(one_and_three):
    model = one_and_three[C]
    policy = model.policy
    with th.no_grad():  # an actor away from the clones
        for p in policy.actor.parameters():
            p.add_(0.05 * th.randn_like(p))
    obs = random_obs_batch(model, 64, seed=2)
    policy.choice_acts.fill_(True)
    with th.no_grad():
        mean = th.stack([m(obs) for m in policy.reference.members]).mean(dim=0)
        assert th.equal(policy._predict(obs), choose(policy.critic, obs, policy.actor(obs), mean))
        assert th.equal(
            model.actor_target(obs), choose(policy.critic_target, obs, model.actor_target.actor(obs), mean)
        )
        policy.choice_acts.fill_(False)
        assert th.equal(policy._predict(obs), mean)  # the clone acts as the mean action


def test_a_saved_model_keeps_its_clones(one_and_three, tmp_path):
    model = one_and_three[C]
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert isinstance(loaded.policy, ReferenceTD3Policy) and loaded.policy.clones == C
    assert _same(loaded.policy.reference, model.policy.reference)


@pytest.mark.parametrize(
    ("agent", "message"),
    [
        ({"clones": 0}, r"^clones must be an integer >= 1; got 0"),
        ({"clones": 3}, r"^clones 3 averages the fast learner's clones: it needs --learner fast"),
    ],
)
def test_bad_values_are_one_line(agent, message):
    with pytest.raises(InvalidConfig, match=message) as err:
        AgentConfig(**agent)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(("name", "value"), [("residual", 0.3), ("clone_proposals", 2)])
def test_options_that_read_one_clone_are_refused_with_more(reach_demos, name, value):
    base = fast(reach_demos).agent
    with pytest.raises(
        InvalidConfig, match=rf"^clones 3 with {name} {value}: {name} reads one clone's network"
    ) as err:
        dataclasses_replace(base, clones=3, **{name: value})
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_count_with_exit_2(tmp_path):
    result = run_tsrl("train", *TINY, "--clones", "0", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "clones must be an integer >= 1; got 0" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
