"""The fast learner's actor taught what the choice between it and its clone does (issue 55).

IBRL's choice (tsrl.agents.reference) acts, per state, by the clone's action where the critic's
smaller head values it above the actor's. On the stack the choice acts far better than either
proposal alone (the return bound's runs, 100 evaluation episodes: seed 1 at 150,000 env steps the
choice 0.90, the clone alone 0.76, the actor alone 0.66; seed 0 at 122,400 0.82, 0.66, 0.55;
studies/learner-from-demos): the actor, held to the demonstrations by the BC anchor and moved by the
critic's action gradient, does not learn where the clone is the better action, so the learner's gain
over its clone stays a per-step mix of two clones, whose disagreements make the fingers flip.

`attach_choice_distillation` registers a step pre-hook on the actor's optimizer, as the BC loss of
tsrl.agents.demos does and after it (whose anchor scales the gradient already accumulated), and
back-propagates `weight * L_D` on every row of the gradient step's batch (own and demonstration
rows) before the step:

    L_D = 1/n * sum_i 1[clone preferred at s_i] * ||pi(s_i) - clone(s_i)||^2

the preference judged by the online critic as the choice judges it (reference.reference_preferred):
Nair et al.'s Q-filter with the clone as the demonstrator at every state. Where the actor is
preferred the row adds nothing, so the critic's action gradient keeps improving it there.
"""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from torch import nn
from torch.utils.hooks import RemovableHandle

from .action_penalty import actor_action, actor_optimizer
from .added_loss import AddedLoss
from .demos import masked_squared_error
from .reference import ReferenceTD3Policy, reference_preferred


def distillation_loss(
    critic: nn.Module, obs: Any, actor_actions: th.Tensor, clone_actions: th.Tensor
) -> tuple[th.Tensor, th.Tensor]:
    """(L_D, mask): the module docstring's loss over the n rows of `obs` for actions (n, k), and the (n,)
    bool mask of rows where the clone is preferred; the gradient flows into `actor_actions` only."""
    with th.no_grad():
        mask = reference_preferred(critic, obs, actor_actions, clone_actions).reshape(-1)
    return masked_squared_error(actor_actions, clone_actions, mask), mask


class ChoiceDistillation(AddedLoss):
    """Step pre-hook of the actor optimizer: back-propagates weight * L_D on the buffer's last batch.

    Records train/distill_loss and train/clone_preferred (the share of rows where the clone is
    preferred) in the model's logger (the latest actor step's)."""

    def loss(self, batch: Any) -> tuple[th.Tensor, dict[str, float]]:
        policy = self.model.policy
        assert isinstance(policy, ReferenceTD3Policy)
        pi = actor_action(self.model, batch.observations)
        with th.no_grad():
            clone = policy.reference(batch.observations)
        loss, mask = distillation_loss(policy.critic, batch.observations, pi, clone)
        return loss, {"distill_loss": loss.item(), "clone_preferred": mask.float().mean().item()}


def attach_choice_distillation(model: OffPolicyAlgorithm, weight: float) -> RemovableHandle:
    """Registers ChoiceDistillation on the actor's optimizer (after creating or loading a fast learner
    whose AgentConfig.distill_choice is > 0, and after its BC loss)."""
    assert weight > 0
    return actor_optimizer(model).register_step_pre_hook(ChoiceDistillation(model, weight))
