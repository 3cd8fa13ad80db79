"""The choice distilled into the fast learner's actor (AgentConfig.distill_choice,
tsrl.agents.choice_distillation): off by default and then the same run; the loss pulls the actor toward
the clone only on the rows where the critic's choice prefers the clone (a hand-built critic); the
actor's step follows grad(actor loss + weight * L_D) after the BC loss; it survives a resume; bad weights
and combinations are one line (exit 2 at the CLI)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch as th
from cli_runner import TINY, run_tsrl
from stable_baselines3.common.logger import configure
from training_helpers import HandCritic, saved_reach_demos, scalar_steps

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env, resume, train
from tsrl.agents.action_penalty import actor_optimizer
from tsrl.agents.choice_distillation import ChoiceDistillation, distillation_loss
from tsrl.agents.config import DemoConfig
from tsrl.agents.demos import BCLoss
from tsrl.agents.reference import choose
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def fast(path: Path, total: int = 400, **agent: object) -> TrainConfig:
    return TrainConfig(
        env_id=REACH, obs="fs1", total_timesteps=total, eval_freq=200, eval_episodes=2, checkpoint_freq=200,
        agent=AgentConfig(learner="fast", batch_size=64, bc_steps=300, demos=DemoConfig(path=str(path)), **agent),
    )  # fmt: skip


def test_the_default_distils_nothing_and_the_run_name_says_when_it_does(reach_demos):
    assert AgentConfig().distill_choice == 0.0
    assert fast(reach_demos).run_name == fast(reach_demos, distill_choice=0.0).run_name
    assert fast(reach_demos, distill_choice=1.0).run_name.endswith("__fast__return-bound-1__distill-choice-1")


def test_the_loss_pulls_the_actor_to_the_clone_only_where_the_choice_takes_the_clone():
    actor = th.tensor([[0.5, 0.0], [0.5, 0.0], [0.2, 0.5], [0.0, 0.3], [0.4, 0.0]], requires_grad=True)
    clone = th.tensor([[-0.5, 0.0], [0.9, 0.0], [0.2, -0.5], [0.0, -0.3], [0.3, 0.0]])
    w = th.tensor([[-1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    critic = HandCritic(w, (1.0, 2.0))  # the choice takes the clone on rows 0 and 1 (test_reference)
    loss, mask = distillation_loss(critic, None, actor, clone)
    assert mask.tolist() == [True, True, False, False, False]
    assert th.equal(
        choose(critic, None, actor.detach(), clone)[mask], clone[mask]
    )  # one rule with the choice
    assert loss.item() == pytest.approx((1.0**2 + 0.4**2) / 5)  # the mean over all 5 rows
    loss.backward()
    assert actor.grad is not None
    expected = th.zeros(5, 2)
    expected[:2] = 2 * (actor.detach()[:2] - clone[:2]) / 5
    th.testing.assert_close(actor.grad, expected)


def test_the_actor_step_adds_the_distillation_after_the_bc_loss(reach_demos):
    plain, distilled = (
        make_agent(c, make_vec_env(c)) for c in (fast(reach_demos), fast(reach_demos, distill_choice=1.0))
    )
    hooks = list(actor_optimizer(distilled)._optimizer_step_pre_hooks.values())  # type: ignore[attr-defined]
    assert [type(h) for h in hooks] == [BCLoss, ChoiceDistillation]  # the anchor scales only the Q gradient
    assert [type(h) for h in actor_optimizer(plain)._optimizer_step_pre_hooks.values()] == [BCLoss]  # type: ignore[attr-defined]
    for model in (plain, distilled):
        model.set_logger(configure(None, []))
        model.learn(400)
    assert 0.0 <= distilled.logger.name_to_value["train/clone_preferred"] <= 1.0
    moved = [
        not th.equal(a, b)
        for a, b in zip(plain.policy.actor.parameters(), distilled.policy.actor.parameters(), strict=True)
    ]
    assert any(moved)  # the same seed, another actor
    for a, b in zip(
        plain.policy.reference.parameters(), distilled.policy.reference.parameters(), strict=True
    ):
        assert th.equal(a, b)  # the clone is frozen either way


def test_a_resumed_run_keeps_the_distillation(reach_demos, tmp_path):
    run_dir = train(fast(reach_demos, total=200, distill_choice=1.0), tmp_path, progress_bar=False)
    resume(run_dir, total_timesteps=400, progress_bar=False)
    assert max(scalar_steps(run_dir, "train/distill_loss")) == 400


@pytest.mark.parametrize("weight", [-1.0, float("nan"), float("inf"), "1"])
def test_a_bad_weight_is_one_line(weight):
    with pytest.raises(InvalidConfig, match=r"^distill_choice .*accepted: a finite number >= 0") as err:
        AgentConfig(distill_choice=weight)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_distilling_without_the_fast_learners_clone_is_one_line():
    with pytest.raises(InvalidConfig, match=r"^distill_choice 1\.0 clones the fast learner's clone") as err:
        AgentConfig(distill_choice=1.0)  # the paper's learner: no clone to distil
    assert "\n" not in str(err.value)


def test_the_cli_refuses_a_bad_weight_with_exit_2(tmp_path):
    result = run_tsrl("train", *TINY, "--distill-choice", "-1", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "distill_choice -1" in result.stderr and len(result.stderr.strip().splitlines()) == 1
