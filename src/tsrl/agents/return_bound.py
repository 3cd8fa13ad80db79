"""The returns the run's episodes achieved as a lower bound of its critic (issue 55).

A transition's discounted return to its episode's end, under the goal it is trained with (its own or
a HER goal; FeatureHerReplayBuffer.returns_to_go), is what the policy that acted achieved from there,
so no better policy is worth less: Q*(s, a) >= G. Monte Carlo augmented actor-critic (Wilcox et al.
2022) puts this bound into the TD target; self-imitation learning (Oh et al. 2018) as a loss on the
values below it. With sparse rewards over long episodes the TD target carries a success back one
step per update, so a critic can stay unable to tell won from lost episodes early in them
(studies/learner-from-demos: AUC 0.52 at the stack's start); the bound gives every state of a won
episode, demonstrations included, its value at once.

`attach_return_bound` registers a step pre-hook on the critic's optimizer, as tsrl.agents.demos does
on the actor's: stable-baselines3 runs `zero_grad(); critic_loss.backward(); step()`, and the hook
back-propagates `weight * L_G` on the batch of that gradient step before the step, without copying
any `train()`:

    L_G = sum_heads 1/n * sum_i max(0, G_i - Q_head(s_i, a_i))^2

so a value under its return is pulled up as TD3's own loss pulls it to its target, and values at or
above their returns feel nothing.
"""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from torch.utils.hooks import RemovableHandle

from .added_loss import AddedLoss
from .her import FeatureHerReplayBuffer
from .reference import heads


def return_bound_loss(values: th.Tensor, returns: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
    """(L_G, share): values (n, heads), returns (n, 1) -> the scalar loss of the module docstring and
    the share of (row, head) values below their return."""
    shortfall = th.relu(returns - values)
    return (shortfall**2).mean(dim=0).sum(), (shortfall > 0).float().mean()


class ReturnBound(AddedLoss):
    """Step pre-hook of the critic optimizer: back-propagates weight * L_G on the buffer's last batch.

    Records train/return_bound_loss and train/below_return (the share of values below their return)
    in the model's logger (the latest gradient step's)."""

    def loss(self, batch: Any) -> tuple[th.Tensor, dict[str, float]] | None:
        buffer = self.model.replay_buffer
        assert isinstance(buffer, FeatureHerReplayBuffer)
        returns = buffer.last_returns
        if returns is None:
            return None
        values = heads(self.model.critic, batch.observations, batch.actions)  # type: ignore[attr-defined]
        loss, below = return_bound_loss(values, returns)
        return loss, {"return_bound_loss": loss.item(), "below_return": below.item()}


def attach_return_bound(model: OffPolicyAlgorithm, weight: float, gamma: float) -> RemovableHandle:
    """Makes the replay buffer compute its rows' returns with `gamma` (the model's) and registers
    ReturnBound on the critic's optimizer (after creating or loading a model whose
    AgentConfig.return_bound is > 0)."""
    assert weight > 0
    buffer = model.replay_buffer
    assert isinstance(buffer, FeatureHerReplayBuffer)
    buffer.track_returns(gamma)
    optimizer = model.critic.optimizer  # type: ignore[attr-defined]
    assert isinstance(optimizer, th.optim.Optimizer)
    return optimizer.register_step_pre_hook(ReturnBound(model, weight))
