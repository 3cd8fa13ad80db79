"""A penalty on the actor's actions (OpenAI baselines' HER `action_l2`, 1.0 on the Fetch tasks).

`attach_action_penalty` registers a step pre-hook on the actor's optimizer, as the BC loss of
tsrl.agents.demos does: stable-baselines3 runs `zero_grad(); actor_loss.backward(); step()`, and the
hook back-propagates `weight * L_a` on the batch of that gradient step (the replay buffer's
`last_batch`, demonstration rows included) before the step, so the step follows
grad(actor_loss + weight * L_a) without copying any `train()`:

    L_a = 1/(n k) * sum_i ||pi(s_i)||^2      (n rows, k action dimensions, actions in [-1, 1])

Small actions near the goal are what it rewards: a policy that has learned to reach the goal pays
for every step it keeps moving there (the push's "reached, then lost", docs/training.md).
"""

from __future__ import annotations

from typing import Any

import torch as th
from sb3_contrib import TQC
from stable_baselines3 import SAC
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from torch.utils.hooks import RemovableHandle

from .added_loss import AddedLoss


def actor_action(model: OffPolicyAlgorithm, obs: dict[str, th.Tensor]) -> th.Tensor:
    """(n, k) actions in [-1, 1] of the model's actor on a batch of (normalised) observations: the
    deterministic action tanh(mean) for SAC and TQC."""
    actor = model.actor  # type: ignore[attr-defined]
    return actor(obs, deterministic=True) if isinstance(model, (SAC, TQC)) else actor(obs)


def action_l2_loss(actions: th.Tensor) -> th.Tensor:
    """Mean over rows and action dimensions of the squared actions (n, k) -> scalar."""
    return (actions**2).mean()


class ActionPenalty(AddedLoss):
    """Step pre-hook of the actor optimizer: back-propagates weight * L_a on the buffer's last batch.

    Records train/action_l2 (L_a of the latest gradient step) in the model's logger."""

    def loss(self, batch: Any) -> tuple[th.Tensor, dict[str, float]]:
        loss = action_l2_loss(actor_action(self.model, batch.observations))
        return loss, {"action_l2": loss.item()}


def actor_optimizer(model: OffPolicyAlgorithm) -> th.optim.Optimizer:
    """The optimizer of the model's actor (DDPG/TD3/SAC/TQC), where losses added to the actor's hook in."""
    policy: Any = model.policy
    optimizer = policy.actor.optimizer
    assert isinstance(optimizer, th.optim.Optimizer)
    return optimizer


def attach_action_penalty(model: OffPolicyAlgorithm, weight: float) -> RemovableHandle:
    """Registers ActionPenalty on the actor's optimizer (after creating or loading a model whose
    AgentConfig.action_l2 is > 0)."""
    assert weight > 0
    return actor_optimizer(model).register_step_pre_hook(ActionPenalty(model, weight))
