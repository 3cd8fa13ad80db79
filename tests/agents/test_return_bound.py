"""The return bound (AgentConfig.return_bound, tsrl.agents.return_bound): off by default and the same
run; each sampled row's return is the discounted sum of its episode's rewards under the row's goal,
written out here step by step; the loss pulls up only values below their returns, and the critic's
step follows grad(critic loss + weight * L_G); demonstration rows carry theirs; it survives a resume;
bad weights and combinations are one line (exit 2 at the CLI)."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th
from cli_runner import TINY, run_tsrl
from stable_baselines3.common.vec_env import VecNormalize
from training_helpers import scalar_steps, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, make_agent, make_vec_env, resume, train
from tsrl.agents.config import DemoConfig, HerConfig
from tsrl.agents.demo_files import save_demos
from tsrl.agents.demonstrators import record_demos
from tsrl.agents.reference import heads
from tsrl.agents.return_bound import ReturnBound, return_bound_loss
from tsrl.exceptions import InvalidConfig


def _model(**agent: object):
    """A tiny reach DDPG agent after its 100 random steps and one episode more."""
    cfg = tiny(**agent)
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(100)
    return model


def _returns_written_out(buffer, row: int, goal: np.ndarray, gamma: float) -> float:
    """The row's return under `goal`, one reward at a time from its step to its episode's end."""
    start, length = int(buffer.ep_start[row, 0]), int(buffer.ep_length[row, 0])
    env = buffer.env.envs[0] if not isinstance(buffer.env, VecNormalize) else buffer.env.venv.envs[0]
    total, discount, reward = 0.0, 1.0, 0.0
    for step in range(row, start + length):
        achieved = buffer.next_observations["achieved_goal"][step, 0]
        reward = float(env.unwrapped.compute_reward(achieved, goal, None))
        total += discount * reward
        discount *= gamma
    return total + discount * reward / (1 - gamma)  # the last reward held past the time limit


def test_the_default_has_no_bound_and_the_same_run():
    assert AgentConfig().return_bound == 0.0
    assert tiny().run_name == tiny(return_bound=0.0).run_name
    assert tiny(return_bound=1.0).run_name.endswith("__s0__return-bound-1")
    default, explicit = _model(), _model(return_bound=0.0)
    for model in (default, explicit):
        np.random.seed(1)
        model.train(gradient_steps=5, batch_size=64)
        assert model.replay_buffer.last_returns is None
    for key, value in default.policy.state_dict().items():
        assert th.equal(explicit.policy.state_dict()[key], value)


def test_returns_to_go_are_the_discounted_rewards_to_the_episodes_end():
    model = _model(return_bound=1.0)
    buffer, gamma = model.replay_buffer, model.gamma
    rows = np.flatnonzero(buffer.ep_length[:, 0] > 0)[[0, 7, 49, 50, 75, 99]]
    zeros = np.zeros(len(rows), dtype=int)
    own = buffer.observations["desired_goal"][rows, 0]
    last = buffer.ep_start[rows, 0] + buffer.ep_length[rows, 0] - 1  # each episode's final step
    reached = buffer.next_observations["achieved_goal"][last, 0]  # a goal its episode ends at
    for goals in (own, reached):
        got = buffer.returns_to_go(rows, zeros, goals, gamma)
        want = [_returns_written_out(buffer, r, g, gamma) for r, g in zip(rows, goals, strict=True)]
        np.testing.assert_allclose(got, want, rtol=1e-6)
    far = own + 10.0  # 10 m away: every reward is the failure's, so every return is it / (1 - gamma)
    failure = float(buffer.env.env_method("compute_reward", reached[:1], far[:1], None)[0][0])
    np.testing.assert_allclose(
        buffer.returns_to_go(rows, zeros, far, gamma), failure / (1 - gamma), rtol=1e-6
    )
    assert np.all(buffer.returns_to_go(rows, zeros, reached, gamma) > failure / (1 - gamma))


def test_a_batchs_returns_are_its_rows_returns_in_its_order():
    model = _model(return_bound=1.0)
    buffer, normalizer = model.replay_buffer, model.get_vec_normalize_env()
    batch = buffer.sample(64, normalizer)
    assert buffer.last_returns.shape == (64, 1)
    goals, want = [], []
    for indices, _, row_goals in buffer._sampled_goals:  # real rows, then relabelled ones
        goals.append(row_goals)
        want += [
            _returns_written_out(buffer, r, g, model.gamma) for r, g in zip(indices, row_goals, strict=True)
        ]
    np.testing.assert_allclose(buffer.last_returns.numpy().ravel(), want, rtol=1e-5)
    normalised = normalizer._normalize_obs(np.concatenate(goals), normalizer.obs_rms["desired_goal"])
    np.testing.assert_allclose(batch.observations["desired_goal"].numpy(), normalised, rtol=1e-5, atol=1e-6)


def test_the_loss_pulls_up_only_values_below_their_returns():
    values = th.tensor([[-3.0, -1.0], [-1.0, -2.5], [0.0, 0.5]], requires_grad=True)
    returns = th.tensor([[-2.0], [-2.0], [-1.0]])
    loss, below = return_bound_loss(values, returns)
    # Below: (0, head 0) by 1 and (1, head 1) by 0.5; per head the mean over 3 rows, summed over heads.
    assert loss.item() == pytest.approx(1.0**2 / 3 + 0.5**2 / 3)
    assert below.item() == pytest.approx(2 / 6)
    loss.backward()
    want = th.tensor([[-2 * 1.0 / 3, 0.0], [0.0, -2 * 0.5 / 3], [0.0, 0.0]])
    assert th.allclose(values.grad, want)  # a descent step raises the two, leaves the rest


def test_the_hook_adds_its_gradient_to_the_critic_loss():
    weight = 0.7
    model = _model(return_bound=1.0)
    batch = model.replay_buffer.sample(64, model.get_vec_normalize_env())
    returns = model.replay_buffer.last_returns
    critic = model.critic

    def critic_grads(extra: bool) -> list[th.Tensor]:
        critic.optimizer.zero_grad()
        values = heads(critic, batch.observations, batch.actions)
        if extra:  # the hook, as the optimizer's step would call it
            values.pow(2).mean().backward()
            ReturnBound(model, weight)(critic.optimizer, (), {})
        else:  # independently: the bound's sum written out, in one backward with the critic loss
            shortfall = (returns - values).clamp_min(0)
            (values.pow(2).mean() + weight * shortfall.pow(2).sum() / len(values)).backward()
        return [p.grad.clone() for p in critic.parameters()]

    with_hook, by_hand = critic_grads(True), critic_grads(False)
    for a, b in zip(with_hook, by_hand, strict=True):
        assert th.allclose(a, b, atol=1e-6)
    assert 0 < model.logger.name_to_value["train/below_return"] <= 1


def test_a_large_bound_lifts_the_values_to_the_returns():
    plain, bounded = _model(), _model(return_bound=20.0)
    for model in (plain, bounded):
        np.random.seed(1)
        model.train(gradient_steps=100, batch_size=64)
    batch = bounded.replay_buffer.sample(256, bounded.get_vec_normalize_env())
    returns = bounded.replay_buffer.last_returns
    with th.no_grad():
        below = [
            float((heads(m.critic, batch.observations, batch.actions) < returns).float().mean())
            for m in (plain, bounded)
        ]
    assert below[1] < 0.5 * below[0]


def test_demonstration_rows_carry_their_returns(tmp_path):
    demos = save_demos(record_demos("tsrl/UR5eReach-v0", 4, obs="fs1", seed=0), tmp_path / "reach.npz")
    model = _model(return_bound=1.0, demos=DemoConfig(path=str(demos), batch_share=0.25))
    buffer = model.replay_buffer
    buffer.sample(64, model.get_vec_normalize_env())
    demo_returns = buffer.demo_buffer.last_returns
    assert buffer.last_returns.shape == (64, 1) and demo_returns.shape == (16, 1)
    assert th.equal(buffer.last_returns[-16:], demo_returns)  # the batch's last rows are the demonstrations'
    demo_buffer = buffer.demo_buffer
    want = [
        _returns_written_out(demo_buffer, r, g, model.gamma)
        for indices, _, goals in demo_buffer._sampled_goals
        for r, g in zip(indices, goals, strict=True)
    ]
    np.testing.assert_allclose(demo_returns.numpy().ravel(), want, rtol=1e-5)


def test_a_resumed_run_keeps_the_bound(tmp_path):
    run_dir = train(tiny(total=200, return_bound=1.0), tmp_path, progress_bar=False)
    resume(run_dir, total_timesteps=400, progress_bar=False)
    assert max(scalar_steps(run_dir, "train/below_return")) == 400


@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf"), "1"])
def test_a_bad_weight_is_one_line(weight):
    with pytest.raises(InvalidConfig, match=r"^return_bound .*accepted: a finite number >= 0") as err:
        AgentConfig(return_bound=weight)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "agent",
    [{"algo": "tqc"}, {"algo": "ddpg", "her": HerConfig(relabel="plain")}, {"algo": "ddpg", "gamma": 1.0}],
)
def test_a_bound_it_cannot_apply_is_one_line(agent):
    with pytest.raises(InvalidConfig, match=r"^return_bound 1\.0 bounds a ddpg, td3 or sac critic") as err:
        AgentConfig(return_bound=1.0, **agent)
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_weight_with_exit_2(tmp_path):
    result = run_tsrl("train", *TINY, "--return-bound", "-1", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "return_bound -1" in result.stderr and len(result.stderr.strip().splitlines()) == 1
