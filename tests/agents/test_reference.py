"""The fast learner's reference (IBRL, tsrl.agents.reference, issue 55): per row, the proposal (actor's
or reference's) whose smaller twin-critic value is higher, the actor's on a tie, in exploring, in the
TD target, and in the kept snapshot that acts deterministically (predict, evaluation, the export); the
reference is a BC clone with dropout (off when it acts) and stays the clone through training and
checkpoints; the normaliser keeps the demonstrations' statistics; the acting gate keeps a snapshot
only when a sequential test measures it better (tsrl.agents.acting_gate)."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3 import TD3
from stable_baselines3.common.logger import configure
from torch import nn

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.acting_gate import (
    EPISODE_KINDS,
    KEPT_EPISODES,
    MAX_CANDIDATE,
    MIN_TO_DROP,
    MIN_TO_KEEP,
    ActingGate,
    GatedTD3,
    prob_better,
)
from tsrl.agents.config import DemoConfig
from tsrl.agents.demo_files import save_demos
from tsrl.agents.demonstrators import record_demos
from tsrl.agents.reference import (
    CANDIDATE,
    EXPLORE,
    KEPT,
    ChosenTarget,
    ReferenceTD3Policy,
    choose,
)
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"


class HandCritic(nn.Module):
    """Twin heads Q_i(s, a) = scale_i * (w . a) with a per-row w: the hand-built critic of the tests."""

    def __init__(self, w: th.Tensor, scales: tuple[float, float]):
        super().__init__()
        self.w, self.scales = w, scales

    def forward(self, obs: object, actions: th.Tensor) -> tuple[th.Tensor, ...]:
        value = (self.w * actions).sum(dim=1, keepdim=True)
        return tuple(scale * value for scale in self.scales)


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
    path = tmp_path_factory.mktemp("demos") / "reach.npz"
    return save_demos(record_demos(REACH, 8, obs="fs1", seed=0), path)


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


def test_exploring_and_the_td_target_take_the_critics_choice_and_the_kept_snapshot_acts(reach_demos):
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
        assert th.equal(policy._predict(obs, deterministic=True), clone)  # nothing kept yet: the clone
        policy.episode_policy = EXPLORE  # the learning choice (TD3 adds the noise)
        assert th.equal(policy._predict(obs, deterministic=True), expected)
        policy.episode_policy = None
        for snapshot in (policy.kept, policy.candidate):  # as the gate takes and keeps them
            snapshot.take(policy.actor, policy.critic)
            snapshot.critic.forward = policy.critic.forward  # type: ignore[method-assign]
        policy.choice_acts.fill_(True)
        assert th.equal(policy._predict(obs, deterministic=True), expected)
        _set_constant(policy.actor, -0.2)  # the actor learns on: the kept snapshot does not move
        assert th.equal(policy._predict(obs, deterministic=True), expected)
        policy.episode_policy = CANDIDATE
        assert th.equal(policy._predict(obs, deterministic=True), expected)
        policy.episode_policy = EXPLORE
        learning = th.where(sign > 0, -0.2, -0.5) * th.ones_like(clone)  # the actor's where sign > 0
        assert th.allclose(policy._predict(obs, deterministic=True), learning, rtol=0, atol=1e-6)
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


def test_the_export_is_the_choice_not_the_actor_alone(reach_demos, tmp_path):
    from tsrl.deploy.contract import POLICY, read_contract
    from tsrl.deploy.export import TOLERANCE, export_policy, task_observations, torch_actions
    from tsrl.deploy.exported import exported_env
    from tsrl.deploy.policy import OnnxPolicy

    cfg = fast(reach_demos)
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    with th.no_grad():  # an actor that has moved away from its clone: the two proposals differ
        for p in model.policy.actor.parameters():
            p.add_(0.3 * th.randn_like(p))
    model.policy.kept.take(model.policy.actor, model.policy.critic)  # as the gate keeps a snapshot
    model.policy.choice_acts.fill_(True)
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
    for module in ("actor", "reference", "critic", "kept", "candidate"):
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
    # A fast policy saved before its kept snapshot (commit ef4c768 or older) is refused in one line.
    state = {k: v for k, v in policies[0].state_dict().items() if not k.startswith(("kept.", "candidate."))}
    with pytest.raises(InvalidConfig, match="before its kept snapshot"):
        policies[0].load_state_dict(state)


def test_prob_better_is_the_posterior_probability_of_a_higher_success_rate():
    from scipy import integrate, stats

    for a, b in (([True] * 8 + [False] * 2, [True] * 11 + [False] * 9), ([True] * 19 + [False], [True] * 40)):
        pa = stats.beta(1 + sum(a), 1 + len(a) - sum(a))
        pb = stats.beta(1 + sum(b), 1 + len(b) - sum(b))
        numeric = integrate.quad(lambda x: pa.pdf(x) * pb.cdf(x), 0, 1)[0]  # noqa: B023
        assert prob_better(a, b) == pytest.approx(numeric, abs=1e-6)
        assert prob_better(a, b) + prob_better(b, a) == pytest.approx(1.0)  # no ties for continuous rates
    assert prob_better([True, False] * 5, [True, False] * 5) == pytest.approx(0.5)
    assert prob_better([], []) == pytest.approx(0.5)


def _run(gate: ActingGate, episodes: int, succeeds: dict[str, bool]) -> tuple[list[str], int]:
    """End `episodes` episodes, an episode of kind k succeeding as succeeds[k], taking a candidate
    snapshot where GatedTD3 does: the kinds in order and the snapshots taken."""
    kinds, taken = [], 0
    for _ in range(episodes):
        if gate.kind == CANDIDATE and gate.candidate is None:
            gate.candidate, taken = [], taken + 1
        kinds.append(gate.kind)
        gate.end_episode(succeeds.get(gate.kind, False))
    return kinds, taken


def test_the_gate_keeps_a_candidate_only_when_measured_better_and_never_goes_back():
    gate = ActingGate()
    # The candidate succeeds, the clone (kept) fails: kept once both are measured MIN_TO_KEEP times.
    kinds, _ = _run(gate, 4 * MIN_TO_KEEP, {CANDIDATE: True})
    assert kinds[:4] == list(EPISODE_KINDS) == [EXPLORE, CANDIDATE, EXPLORE, KEPT]
    assert gate.snapshots_kept == 0 and not gate.choice_acts  # at its 10th, the clone had 9 measured
    _run(gate, 2, {CANDIDATE: True})  # the candidate's 11th episode, the clone's 10th before it
    assert gate.snapshots_kept == 1 and gate.choice_acts and gate.candidate is None
    assert gate.kept == [True] * (MIN_TO_KEEP + 1) and gate.kept_episodes == 0  # its measures came with it
    # The new kept policy is measured KEPT_EPISODES times in its place, which then explores; the
    # candidates fail and are dropped after MIN_TO_DROP episodes each: the kept policy stays.
    kinds, taken = _run(gate, 4 * KEPT_EPISODES + 20 * MIN_TO_DROP + 2, {KEPT: True})
    assert kinds.count(KEPT) == KEPT_EPISODES and kinds[-4:] == [EXPLORE, CANDIDATE, EXPLORE, EXPLORE]
    assert gate.kept == [True] * (MIN_TO_KEEP + 1 + KEPT_EPISODES) and gate.snapshots_kept == 1
    assert kinds.count(CANDIDATE) == MIN_TO_DROP * taken and taken > 1 and gate.candidate is None
    # A candidate as good as the kept policy is not kept: dropped undecided after MAX_CANDIDATE.
    gate = ActingGate(episodes=1, kept=[True, False] * 20, kept_episodes=KEPT_EPISODES, snapshots_kept=1)
    gate.candidate = []
    for i in range(MAX_CANDIDATE):
        assert gate.kind == CANDIDATE
        gate.end_episode(i % 2 == 0)
        assert gate.snapshots_kept == 1 and (gate.candidate is None) == (i == MAX_CANDIDATE - 1), i
        gate.episodes += 3  # the explore, explore and (measured out) kept places in between


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
    for critic in (policy.critic, policy.candidate.critic):  # the candidate snapshot's too
        critic.forward = ObsCritic().forward  # type: ignore[method-assign]
    model.train = lambda *args, **kwargs: None  # type: ignore[method-assign]  # networks fixed: known choices
    model.set_logger(configure(None, []))
    model.learn(cfg.total_timesteps)
    steps = int(venv.get_attr("spec")[0].max_episode_steps)
    episodes = cfg.total_timesteps // steps
    assert model.gate.episodes == episodes >= 8
    assert (
        model.gate.candidate is not None
        and len(model.gate.candidate) == len(model.gate.kept) == episodes // 4
    )
    assert model.gate.snapshots_kept == 0  # too few measured to keep the candidate
    buffer = model.replay_buffer
    for episode in range(episodes):
        rows = slice(episode * steps, (episode + 1) * steps)
        first = venv.normalize_obs({k: v[rows, 0] for k, v in buffer.observations.items()})["observation"][
            :, :1
        ]
        choice = np.where(first > 0, 0.5, -0.5) * np.ones_like(buffer.actions[rows, 0])
        acted = {KEPT: np.full_like(choice, -0.5), CANDIDATE: choice}  # nothing kept: the clone
        kind = EPISODE_KINDS[episode % 4]
        if kind == EXPLORE:  # the learning choice plus noise
            assert not np.allclose(buffer.actions[rows, 0], choice, atol=1e-6), episode
        else:  # no noise: exactly the measured policy's action
            np.testing.assert_allclose(buffer.actions[rows, 0], acted[kind], atol=1e-6, err_msg=str(episode))
    assert (buffer.actions[: episodes * steps] > 0).any()  # the actor acted somewhere: the test can fail
    policy.kept.take(policy.actor, policy.critic)  # as if the candidate had measured better
    policy.choice_acts.fill_(True)
    model.save(tmp_path / "model.zip")
    loaded = TD3.load(
        tmp_path / "model.zip",
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert bool(loaded.policy.choice_acts) and loaded.gate.episodes == episodes
    pairs = zip(loaded.policy.kept.parameters(), policy.actor.parameters(), strict=False)
    assert all(th.equal(a, b) for a, b in pairs)  # the kept snapshot came back with the policy
