"""The fast learner's reference (IBRL, tsrl.agents.reference, issue 55): per row, the actor's proposal
is taken only where its smallest twin-critic value is above the reference's largest, else the
reference's, in acting (predict, and so evaluation), in the TD target, and in the exported policy; the
reference is a BC clone with dropout (off when it acts) and stays the clone through training and
checkpoints; the normaliser keeps the demonstrations' statistics."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3 import TD3
from stable_baselines3.common.logger import configure
from torch import nn
from training_helpers import HandCritic, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.acting_gate import EPISODE_KINDS, MIN_EPISODES, WINDOW, ActingGate, GatedTD3
from tsrl.agents.config import DemoConfig
from tsrl.agents.reference import CHOICE, CLONE, ChosenTarget, ReferenceTD3Policy, ResidualHead, choose
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"


def test_choose_takes_the_proposal_whose_smaller_head_is_higher_the_actor_on_a_tie():
    actor = th.tensor([[0.5, 0.0], [0.5, 0.0], [0.2, 0.5], [0.0, 0.3], [0.4, 0.0]])
    reference = th.tensor([[-0.5, 0.0], [0.9, 0.0], [0.2, -0.5], [0.0, -0.3], [0.3, 0.0]])
    w = th.tensor([[-1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    # Heads Q = (1, 2) * w.a, smaller head w.a. Row 0: the reference (0.5 against -0.5). Row 1: the
    # reference (0.9 against 0.5). Row 2: a tie (0.2 each, different actions): the actor. Row 3: the
    # actor (0.3 against -0.3). Row 4: the actor (0.4 against 0.3).
    chosen = choose(HandCritic(w, (1.0, 2.0)), None, actor, reference)  # type: ignore[arg-type]
    assert th.equal(chosen, th.stack([reference[0], reference[1], actor[2], actor[3], actor[4]]))
    # Heads that disagree in sign (Q2 = -3 w.a): the smaller head is -3 w.a where w.a > 0, else w.a.
    # Row 0: actor -0.5, reference -1.5: the actor. Row 1: -1.5 against -2.7: the actor. Row 2: a tie.
    # Row 3: actor -0.9, reference -0.3: the reference. Row 4: actor -1.2, reference -0.9: the reference.
    disagree = choose(HandCritic(w, (1.0, -3.0)), None, actor, reference)  # type: ignore[arg-type]
    assert th.equal(disagree, th.stack([actor[0], actor[1], actor[2], reference[3], reference[4]]))


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def fast(path: Path, warmup: int | None = None) -> TrainConfig:
    demos = DemoConfig(path=str(path), bc_anchor_warmup=warmup)
    return TrainConfig(
        env_id=REACH, obs="fs1", total_timesteps=400,
        agent=AgentConfig(learner="fast", batch_size=64, bc_steps=300, demos=demos),
    )  # fmt: skip


def _set_constant(actor: nn.Module, value: float) -> None:
    """A TD3 actor whose every action component is `value` (last Linear: zero weights, atanh bias)."""
    last = [m for m in actor.modules() if isinstance(m, nn.Linear)][-1]
    with th.no_grad():
        last.weight.zero_()
        last.bias.fill_(float(np.arctanh(value)))


def _obs_batch(model: TD3, n: int, seed: int) -> dict[str, th.Tensor]:
    rng = np.random.default_rng(seed)
    space = model.observation_space
    return {k: th.as_tensor(rng.normal(0, 1, (n, *space[k].shape)), dtype=th.float32) for k in space.spaces}  # type: ignore[index]


def test_acting_and_the_td_target_take_the_critics_choice(reach_demos):
    cfg = fast(reach_demos)
    model = make_agent(cfg, make_vec_env(cfg))
    policy = model.policy
    assert isinstance(policy, ReferenceTD3Policy) and isinstance(model.actor_target, ChosenTarget)
    _set_constant(policy.actor, 0.5)
    _set_constant(policy.actor_target.actor, 0.5)
    _set_constant(policy.reference, -0.5)
    obs = _obs_batch(model, 64, seed=1)
    sign = th.where(obs["observation"][:, :1] > 0, 1.0, -1.0)  # the critics prefer +a where it is > 0
    for critic in (policy.critic, policy.critic_target):
        w = sign.repeat(1, model.action_space.shape[0])  # type: ignore[index]
        hand = HandCritic(w, (1.0, 2.0))
        critic.forward = hand.forward  # type: ignore[method-assign]
    expected = sign * 0.5 * th.ones(64, model.action_space.shape[0])  # type: ignore[index]
    clone = -0.5 * th.ones(64, model.action_space.shape[0])  # type: ignore[index]
    with th.no_grad():
        assert th.equal(model.actor_target(obs), expected)  # the TD target: always the choice
        assert th.equal(
            policy._predict(obs, deterministic=True), clone
        )  # before the gate lets the choice act
        policy.choice_acts.fill_(True)
        assert th.equal(policy._predict(obs, deterministic=True), expected)
        policy.episode_policy = CLONE  # a measuring episode of the clone overrides the gate
        assert th.equal(policy._predict(obs, deterministic=True), clone)
        policy.episode_policy = None
    actions, _ = model.predict({k: v.numpy() for k, v in obs.items()}, deterministic=True)
    np.testing.assert_array_equal(actions, expected.numpy())
    assert 0.2 < model.actor_target.reference_share < 0.8  # both proposals won rows: the test can fail


def test_the_reference_stays_the_clone_and_the_normaliser_the_demonstrations(reach_demos, tmp_path):
    cfg = fast(reach_demos, warmup=0)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    policy = model.policy
    clone = [p.clone() for p in policy.actor.parameters()]
    for copy in (policy.reference, policy.actor_target):  # pretrain_actor set both to the clone
        assert all(th.equal(a, b) for a, b in zip(copy.parameters(), clone, strict=True))
    # The clone has BC's dropout after each hidden layer (the actor none), off whenever it acts.
    dropouts = [m for m in policy.reference.modules() if isinstance(m, nn.Dropout)]
    assert len(dropouts) == len(cfg.agent.net_arch) and all(m.p == cfg.agent.bc_dropout for m in dropouts)
    assert not any(isinstance(m, nn.Dropout) for m in policy.actor.modules())
    stats = {k: (rms.mean.copy(), rms.var.copy()) for k, rms in venv.obs_rms.items()}
    assert not venv.training
    model.set_logger(configure(None, []))
    model.learn(400)
    assert all(th.equal(a, b) for a, b in zip(policy.reference.parameters(), clone, strict=True))
    assert not all(th.equal(a, b) for a, b in zip(policy.actor.parameters(), clone, strict=True))
    assert not any(m.training for m in policy.reference.modules())  # TD3's train() left it acting
    for key, (mean, var) in stats.items():  # 400 env steps, and the statistics did not move
        np.testing.assert_array_equal(venv.obs_rms[key].mean, mean)
        np.testing.assert_array_equal(venv.obs_rms[key].var, var)
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert isinstance(loaded.policy, ReferenceTD3Policy)
    assert all(th.equal(a, b) for a, b in zip(loaded.policy.reference.parameters(), clone, strict=True))
    obs = _obs_batch(model, 32, seed=2)
    np.testing.assert_array_equal(
        loaded.predict({k: v.numpy() for k, v in obs.items()}, deterministic=True)[0],
        model.predict({k: v.numpy() for k, v in obs.items()}, deterministic=True)[0],
    )


@pytest.mark.parametrize("residual", [0.0, 0.3])
def test_the_export_is_the_choice_not_the_actor_alone(reach_demos, tmp_path, residual):
    from tsrl.deploy.contract import POLICY, read_contract
    from tsrl.deploy.export import TOLERANCE, export_policy, task_observations, torch_actions
    from tsrl.deploy.exported import exported_env
    from tsrl.deploy.policy import OnnxPolicy

    base = fast(reach_demos)
    cfg = dataclasses_replace(base, agent=dataclasses_replace(base.agent, residual=residual))
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    with th.no_grad():  # an actor that has moved away from its clone: the two proposals differ
        for p in model.policy.actor.parameters():
            p.add_(0.05 * th.randn_like(p))
    model.policy.choice_acts.fill_(True)  # as the gate sets it once the choice measured better
    out = tmp_path / "export"
    export_policy(model, venv, cfg, out, None, None, None)
    contract = read_contract(out)
    observations = task_observations(exported_env(out, contract), 500, seed=7)
    keys = tuple(i.name for i in contract.policy.inputs)
    onnx = OnnxPolicy(out / POLICY, keys).batch(observations)
    np.testing.assert_allclose(onnx, torch_actions(model, venv, observations), rtol=0, atol=TOLERANCE)
    obs = venv.normalize_obs(observations)
    with th.no_grad():
        tensors = {k: th.as_tensor(v, dtype=th.float32) for k, v in obs.items()}
        actor = model.policy.actor(tensors).numpy()
        reference = model.policy.reference(tensors).numpy()
    from_reference = np.all(np.abs(onnx - reference) < TOLERANCE, axis=1)
    from_actor = np.all(np.abs(onnx - actor) < TOLERANCE, axis=1)
    assert np.all(from_reference | from_actor)
    assert from_reference.any() and from_actor.any()  # both were chosen: the export is not one of them


def test_a_killed_run_resumes_with_its_reference_deterministically_and_an_old_run_is_refused(
    reach_demos, tmp_path, monkeypatch
):
    import shutil

    from tsrl.agents import resume, train
    from tsrl.agents.checkpoint import load_policy, usable_checkpoint
    from tsrl.agents.learners import LayerNormTD3Policy
    from tsrl.agents.run_folder import checkpoint_dirs
    from tsrl.exceptions import InvalidConfig

    cfg = dataclasses_replace(
        fast(reach_demos, warmup=0), total_timesteps=400, checkpoint_freq=200, eval_freq=200
    )
    run_dir = train(cfg, tmp_path / "a", progress_bar=False)
    copies = [tmp_path / name / run_dir.name for name in ("b", "c")]
    for copy in copies:  # killed after the first checkpoint, resumed from it
        shutil.copytree(run_dir, copy)
        shutil.rmtree(checkpoint_dirs(copy)[-1])
        resume(copy, progress_bar=False)
    policies = [load_policy(usable_checkpoint(d, True, False), TD3)[0].policy for d in (run_dir, *copies)]  # type: ignore[arg-type]
    # Deterministic given the checkpoint (as every run: the env restarts with a new episode on resume).
    for module in ("actor", "reference", "critic"):
        pairs = zip(*(getattr(p, module).parameters() for p in policies[1:]), strict=True)
        assert all(th.equal(a, b) for a, b in pairs), module
    # The reference came back with the checkpoint and is still the clone of the uninterrupted run.
    pairs = zip(*(p.reference.parameters() for p in policies[:2]), strict=True)
    assert all(th.equal(a, b) for a, b in pairs)
    # A fast run whose checkpoints hold no reference (tsrl 0.2.0's) is refused, not resumed as a hybrid.
    monkeypatch.setattr(AgentConfig, "has_reference", property(lambda self: False))
    old = train(cfg, tmp_path / "old", progress_bar=False)
    monkeypatch.undo()
    assert type(load_policy(usable_checkpoint(old, True, False), TD3)[0].policy) is LayerNormTD3Policy  # type: ignore[arg-type]
    with pytest.raises(InvalidConfig, match="tsrl 0.2.0"):
        resume(old, total_timesteps=600, progress_bar=False)


def test_the_gate_lets_the_choice_act_only_when_measured_strictly_better():
    gate = ActingGate()
    kinds = []
    for _ in range(4 * MIN_EPISODES - 1):  # one clone episode short of MIN_EPISODES each
        kinds.append(gate.kind)
        gate.end_episode(gate.kind == CHOICE)  # the choice succeeds, the clone fails
    assert kinds[:4] == list(EPISODE_KINDS) == ["explore", CHOICE, "explore", CLONE]
    assert len(gate.measured[CHOICE]) == MIN_EPISODES and len(gate.measured[CLONE]) == MIN_EPISODES - 1
    assert not gate.choice_acts  # too few measured clone episodes
    gate.end_episode(False)
    assert gate.choice_acts and gate.success(CHOICE) == 1.0 and gate.success(CLONE) == 0.0
    while len(gate.measured[CLONE]) < WINDOW:  # the clone succeeds from now on
        gate.end_episode(gate.kind == CLONE)
    assert gate.success(CLONE) == (WINDOW - MIN_EPISODES) / WINDOW
    # Measured once (it is frozen): its place in the cycle now explores, its window stays.
    kinds = []
    for _ in range(4 * WINDOW):  # the choice fails: its window forgets its successes
        kinds.append(gate.kind)
        gate.end_episode(False)
    assert kinds[:4] == ["explore", CHOICE, "explore", "explore"] and CLONE not in kinds
    assert gate.measured[CLONE] == [False] * MIN_EPISODES + [True] * (WINDOW - MIN_EPISODES)
    assert gate.success(CHOICE) == 0.0 and not gate.choice_acts
    for _ in range(4 * WINDOW):  # the choice succeeds as often as the clone: equal is not better
        gate.end_episode(gate.kind == CHOICE and gate.episodes % 8 == 1)
    assert gate.success(CHOICE) == gate.success(CLONE) == 0.5 and not gate.choice_acts


def test_the_gate_measures_only_episodes_from_the_tasks_own_starts(reach_demos):
    for prob in (1.0, None):  # every episode from a demonstration's state, then none
        base = fast(reach_demos, warmup=0)
        cfg = dataclasses_replace(
            base,
            agent=dataclasses_replace(
                base.agent, demos=dataclasses_replace(base.agent.demos, reset_prob=prob)
            ),
        )
        model = make_agent(cfg, make_vec_env(cfg))
        assert isinstance(model, GatedTD3)
        model.train = lambda *args, **kwargs: None  # type: ignore[method-assign]  # the gate alone
        model.learn(300)
        assert model._episode_num > 0
        assert model.gate.episodes == (0 if prob else model._episode_num)


class ObsCritic(nn.Module):
    """Twin heads Q_i = scale_i * sign(first observation entry) * sum(a): with a constant actor (0.5)
    and clone (-0.5), the choice is the actor's action where that entry is > 0, else the clone's."""

    def forward(self, obs: dict[str, th.Tensor], actions: th.Tensor) -> tuple[th.Tensor, ...]:
        value = th.sign(obs["observation"][:, :1]) * actions.sum(dim=1, keepdim=True)
        return value, 2 * value


def test_training_episodes_cycle_through_the_kinds_and_the_decision_is_saved_with_the_policy(
    reach_demos, tmp_path
):
    cfg = fast(reach_demos, warmup=0)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    assert isinstance(model, GatedTD3)
    policy = model.policy
    _set_constant(policy.actor, 0.5)
    _set_constant(policy.reference, -0.5)
    policy.critic.forward = ObsCritic().forward  # type: ignore[method-assign]
    model.train = lambda *args, **kwargs: None  # type: ignore[method-assign]  # networks fixed: known choices
    model.set_logger(configure(None, []))
    model.learn(cfg.total_timesteps)
    steps = int(venv.get_attr("spec")[0].max_episode_steps)
    episodes = cfg.total_timesteps // steps
    assert model.gate.episodes == episodes >= 8
    assert len(model.gate.measured[CHOICE]) == len(model.gate.measured[CLONE]) == episodes // 4
    buffer = model.replay_buffer
    for episode in range(episodes):
        rows = slice(episode * steps, (episode + 1) * steps)
        first = venv.normalize_obs({k: v[rows, 0] for k, v in buffer.observations.items()})["observation"][
            :, :1
        ]
        choice = np.where(first > 0, 0.5, -0.5) * np.ones_like(buffer.actions[rows, 0])
        acted = {CLONE: np.full_like(choice, -0.5), CHOICE: choice}
        kind = EPISODE_KINDS[episode % 4]
        if kind == "explore":  # the choice plus noise
            assert not np.allclose(buffer.actions[rows, 0], choice, atol=1e-6), episode
        else:  # no noise: exactly the measured policy's action
            np.testing.assert_allclose(buffer.actions[rows, 0], acted[kind], atol=1e-6, err_msg=str(episode))
    assert (buffer.actions[: episodes * steps] > 0).any()  # the actor acted somewhere: the test can fail
    policy.choice_acts.fill_(True)  # as if the choice had measured better
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert bool(loaded.policy.choice_acts) and loaded.gate.episodes == episodes


def test_a_residual_actor_starts_as_the_clone_moves_at_most_alpha_from_it_and_trains_alone(
    reach_demos, tmp_path
):
    base = fast(reach_demos, warmup=0)
    cfg = dataclasses_replace(base, agent=dataclasses_replace(base.agent, residual=0.3))
    assert cfg.run_name.replace("__residual-0.3", "") == base.run_name != cfg.run_name  # its own folder
    model = make_agent(cfg, make_vec_env(cfg))
    policy = model.policy
    assert isinstance(policy, ReferenceTD3Policy) and isinstance(policy.actor.mu, ResidualHead)
    obs = _obs_batch(model, 64, seed=3)
    with th.no_grad():
        clone = policy.reference(obs)
        assert th.equal(policy.actor(obs), clone)  # the residual starts at zero
        assert th.equal(policy.actor_target.actor(obs), clone)
        assert not th.equal(clone, th.zeros_like(clone))  # the clone was fitted: the check can fail
    reference_ids = {id(p) for p in policy.reference.parameters()}
    assert not reference_ids & {id(p) for g in policy.actor.optimizer.param_groups for p in g["params"]}
    _set_constant(policy.actor.mu.residual, 0.99)  # the largest correction: +0.99 * alpha everywhere
    with th.no_grad():
        moved = policy.actor(obs) - clone
    free = clone < 1 - 0.3  # rows and components the clamp leaves alone
    assert th.allclose(moved[free], th.full_like(moved[free], 0.3 * 0.99)) and free.any()
    assert (moved.abs() <= 0.3 + 1e-6).all()
    kept = [p.clone() for p in policy.reference.parameters()]
    model.set_logger(configure(None, []))
    model.learn(400)
    assert all(th.equal(a, b) for a, b in zip(policy.reference.parameters(), kept, strict=True))
    with th.no_grad():
        assert (policy.actor(obs) - policy.reference(obs)).abs().max() <= 0.3 + 1e-6
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert isinstance(loaded.policy, ReferenceTD3Policy) and loaded.policy.residual == 0.3
    with th.no_grad():
        assert th.equal(loaded.policy.actor(obs), policy.actor(obs))


@pytest.mark.parametrize("residual", [-0.1, 1.5, float("nan"), True])
def test_a_residual_outside_0_1_is_refused_in_one_line(residual):
    with pytest.raises(InvalidConfig, match=r"^residual .*accepted: a number in \[0, 1\]") as err:
        AgentConfig(residual=residual)
    assert "\n" not in str(err.value)


def test_a_residual_without_the_fast_learners_clone_is_refused(reach_demos):
    with pytest.raises(InvalidConfig, match="needs --learner fast.*got learner 'paper'"):
        AgentConfig(learner="paper", residual=0.3, demos=DemoConfig(path=str(reach_demos)))
    with pytest.raises(InvalidConfig, match="demos None"):
        AgentConfig(learner="fast", residual=0.3)
