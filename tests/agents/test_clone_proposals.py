"""Thinned clones as further proposals of the fast learner's choice (AgentConfig.clone_proposals,
tsrl.agents.reference): the rule over many proposals is the two-proposal choice's (a hand-built critic);
each thinned clone is the clone with its fixed dropout mask (an independent computation); acting, the TD
target and the export take the best of all proposals; the masks are the same in every run and leave the
networks' initial draws alone; they come back with a saved model; bad values are one line (exit 2)."""

from __future__ import annotations

import copy
from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
import torch as th
from cli_runner import TINY, run_tsrl
from stable_baselines3 import TD3
from torch import nn
from training_helpers import fast_reach, random_obs_batch, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, make_agent, make_vec_env
from tsrl.agents.reference import ReferenceTD3Policy, ThinnedClones, choose, choose_among
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"
K = 6


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


class WeightsInObs(nn.Module):
    """Twin heads Q_i(s, a) = scale_i * (w(s) . a), w(s) the observation (a tensor) or the first entries
    of its "observation": the rows' weights travel with the rows the choice repeats."""

    def forward(self, obs: th.Tensor | dict[str, th.Tensor], actions: th.Tensor) -> tuple[th.Tensor, ...]:
        w = obs if isinstance(obs, th.Tensor) else obs["observation"][:, : actions.shape[1]]
        value = (w * actions).sum(dim=1, keepdim=True)
        return value, 2.0 * value


def test_the_rule_over_many_proposals_is_the_highest_smaller_head_the_first_on_a_tie():
    w = th.tensor([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0], [-1.0, 0.0]])
    proposals = th.tensor(
        [
            [[0.1, 0.0], [0.0, 0.5], [0.2, 0.2], [0.3, 0.0]],  # the actor
            [[0.4, 0.0], [0.0, 0.1], [0.1, 0.3], [-0.2, 0.0]],  # the clone
            [[0.9, 0.0], [0.0, -0.1], [0.3, 0.1], [-0.5, 0.0]],  # a thinned clone
        ]
    )
    # Heads (1, 2) * w.a (w the row's observation), smaller head w.a. Row 0: 0.1, 0.4, 0.9: the thinned clone. Row 1: 0.5, 0.1,
    # -0.1: the actor. Row 2: 0.4 each: the actor (first). Row 3: -0.3, 0.2, 0.5: the thinned clone.
    chosen, index = choose_among(WeightsInObs(), w, proposals)
    assert index.tolist() == [2, 0, 0, 2]
    assert th.equal(chosen, th.stack([proposals[2, 0], proposals[0, 1], proposals[0, 2], proposals[2, 3]]))
    # With two proposals it is the choice between the actor and the clone, row for row.
    rng = th.Generator().manual_seed(3)
    actor, clone, w = (th.rand(200, 3, generator=rng) * 2 - 1 for _ in range(3))
    critic = WeightsInObs()
    assert th.equal(choose_among(critic, w, th.stack((actor, clone)))[0], choose(critic, w, actor, clone))


def test_each_thinned_clone_is_the_clone_with_its_fixed_mask(reach_demos):
    cfg = fast_reach(reach_demos, clone_proposals=K)
    model = make_agent(cfg, make_vec_env(cfg))
    policy = model.policy
    assert isinstance(policy, ReferenceTD3Policy) and isinstance(policy.thinned, ThinnedClones)
    obs = random_obs_batch(model, 16, seed=1)
    p = cfg.agent.bc_dropout
    masks = list(policy.thinned._buffers.values())
    assert len(masks) == len(cfg.agent.net_arch)
    for mask, width in zip(masks, cfg.agent.net_arch, strict=True):
        assert mask.shape == (K, width)
        assert mask.unique().tolist() == [
            0.0,
            pytest.approx(1.0 / (1.0 - p)),
        ]  # dropped, or kept and rescaled
    with th.no_grad():
        thinned = policy.thinned(obs)
        assert thinned.shape == (K, 16, model.action_space.shape[0])  # type: ignore[index]
        features = policy.reference.extract_features(obs, policy.reference.features_extractor)
        for j in range(K):  # the clone's layers in order, each Dropout a multiplication by mask j
            x, masks_j = features, iter(m[j] for m in masks)
            for layer in copy.deepcopy(policy.reference.mu):
                x = x * next(masks_j) if isinstance(layer, nn.Dropout) else layer(x)
            np.testing.assert_allclose(thinned[j].numpy(), x.numpy(), rtol=0, atol=1e-6)
        assert not th.allclose(thinned[0], thinned[1])  # different masks, different proposals


def test_acting_and_the_td_target_take_the_best_of_all_proposals(reach_demos):
    cfg = fast_reach(reach_demos, clone_proposals=K)
    model = make_agent(cfg, make_vec_env(cfg))
    policy = model.policy
    obs = random_obs_batch(model, 64, seed=2)
    n_actions = model.action_space.shape[0]  # type: ignore[index]
    w = obs["observation"][:, :n_actions]
    for critic in (policy.critic, policy.critic_target):
        critic.forward = WeightsInObs().forward  # type: ignore[method-assign]
    policy.choice_acts.fill_(True)
    with th.no_grad():
        for actor, chosen in (
            (policy.actor, policy._predict(obs)),
            (model.actor_target.actor, model.actor_target(obs)),
        ):
            proposals = th.cat((th.stack((actor(obs), policy.reference(obs))), policy.thinned(obs)))
            values = (proposals * w).sum(dim=2)  # (P, n): the hand critic's smaller head
            best = values.argmax(dim=0)
            assert th.equal(chosen, proposals[best, th.arange(64)])
            assert (best >= 2).any() and (best < 2).any()  # thinned clones won rows and so did others
    assert 0 < model.actor_target.reference_share <= 1


def test_the_masks_are_every_runs_and_leave_the_networks_and_a_saved_model_keeps_them(reach_demos, tmp_path):
    models = {}
    for name, seed, proposals in (("off", 0, 0), ("on", 0, K), ("other seed", 1, K)):
        cfg = fast_reach(reach_demos, seed=seed, clone_proposals=proposals)
        models[name] = make_agent(cfg, make_vec_env(cfg))
    off, on, other = (models[k].policy for k in ("off", "on", "other seed"))
    assert off.thinned is None
    for a, b in zip(off.parameters(), on.parameters(), strict=True):  # the masks drew nothing of the seed's
        assert th.equal(a, b)
    for a, b in zip(on.thinned.buffers(), other.thinned.buffers(), strict=True):  # THINNING_SEED's masks
        assert th.equal(a, b)
    models["on"].save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert isinstance(loaded.policy, ReferenceTD3Policy) and loaded.policy.clone_proposals == K
    on.choice_acts.fill_(True)
    loaded.policy.choice_acts.fill_(True)
    obs = {k: v.numpy() for k, v in random_obs_batch(models["on"], 32, seed=3).items()}
    np.testing.assert_array_equal(
        loaded.predict(obs, deterministic=True)[0], models["on"].predict(obs, deterministic=True)[0]
    )


def test_the_export_is_the_choice_among_all_proposals(reach_demos, tmp_path):
    from tsrl.deploy.contract import POLICY, read_contract
    from tsrl.deploy.export import TOLERANCE, export_policy, task_observations, torch_actions
    from tsrl.deploy.exported import exported_env
    from tsrl.deploy.policy import OnnxPolicy

    cfg = fast_reach(reach_demos, clone_proposals=K)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    with th.no_grad():  # an actor that has moved away from its clone
        for p in model.policy.actor.parameters():
            p.add_(0.05 * th.randn_like(p))
    model.policy.choice_acts.fill_(True)
    out = tmp_path / "export"
    export_policy(model, venv, cfg, out, None, None, None)
    contract = read_contract(out)
    observations = task_observations(exported_env(out, contract), 300, seed=7)
    onnx = OnnxPolicy(out / POLICY, tuple(i.name for i in contract.policy.inputs)).batch(observations)
    np.testing.assert_allclose(onnx, torch_actions(model, venv, observations), rtol=0, atol=TOLERANCE)
    with th.no_grad():
        obs = {k: th.as_tensor(v, dtype=th.float32) for k, v in venv.normalize_obs(observations).items()}
        thinned = model.policy.thinned(obs).numpy()
    assert np.any(np.all(np.abs(onnx[None] - thinned) < TOLERANCE, axis=2))  # a thinned clone was chosen


@pytest.mark.parametrize("value", [-1, 1.5, True])
def test_a_bad_count_is_one_line(value):
    with pytest.raises(InvalidConfig, match=r"^clone_proposals must be an integer >= 0") as err:
        AgentConfig(clone_proposals=value)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_proposals_without_the_clone_or_its_dropout_are_one_line(reach_demos):
    with pytest.raises(
        InvalidConfig, match=r"^clone_proposals 4 thins the fast learner's clone: it needs"
    ) as err:
        AgentConfig(clone_proposals=4)  # the paper's learner: no clone
    assert "\n" not in str(err.value)
    base = fast_reach(reach_demos).agent
    with pytest.raises(
        InvalidConfig, match=r"^clone_proposals 4 thins the clone by its dropout, but bc_dropout is 0"
    ) as err:
        dataclasses_replace(base, clone_proposals=4, bc_dropout=0.0)
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_count_with_exit_2(tmp_path):
    result = run_tsrl("train", *TINY, "--clone-proposals", "-2", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "clone_proposals must be an integer >= 0; got -2" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
