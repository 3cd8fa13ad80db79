"""A frozen reference policy beside the actor, the critic choosing between them (IBRL, Hu et al. 2023).

The fast learner's policy keeps a copy of its behaviour-cloned actor, frozen (`reference`). Wherever
TD3 takes the actor's action, it takes instead, per row, the proposal the critic values more:

    a(s) = reference(s) if min_i Q_i(s, reference(s)) > min_i Q_i(s, actor(s)) else actor(s)

- acting and evaluation (the policy's `_predict`, and so the export): the critic's twin heads;
- the TD target (TD3's `actor_target`): the target critic's twin heads on the target actor's and the
  reference's proposals, before TD3's target smoothing noise is added to the chosen one.

A run so never acts worse than its clone where the critic ranks the two correctly, and the actor is
free to climb. The actor's own loss is TD3's (with the BC anchor of tsrl.agents.demos when set).
`ReferenceTD3Policy` is a module-level class, so saved models load with it; the reference is part
of the policy's state dict (checkpoints keep it).
"""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.type_aliases import PyTorchObs
from torch import nn

from .learners import LayerNormTD3Policy


def min_q(critic: nn.Module, obs: PyTorchObs, actions: th.Tensor) -> th.Tensor:
    """(n, 1) the smallest of the critic's heads (SB3's ContinuousCritic: a tuple of (n, 1))."""
    return th.min(th.cat(critic(obs, actions), dim=1), dim=1, keepdim=True).values


def choose(
    critic: nn.Module, obs: PyTorchObs, actor_actions: th.Tensor, reference_actions: th.Tensor
) -> th.Tensor:
    """(n, k): per row, the reference's action where min_i Q_i is strictly higher for it, else the actor's."""
    take_reference = min_q(critic, obs, reference_actions) > min_q(critic, obs, actor_actions)
    return th.where(take_reference, reference_actions, actor_actions)


class ChosenTarget(nn.Module):
    """TD3's target actor whose action is the choice (module docstring) between its own proposal and the
    reference's, valued by the target critic. Only the target actor is a registered child: its
    parameters are TD3's polyak targets, and the reference and critic stay where the policy keeps them.
    `reference_share` is the share of rows the reference won in the last call."""

    _reference: nn.Module
    _critic: nn.Module

    def __init__(self, actor_target: nn.Module, reference: nn.Module, critic_target: nn.Module):
        super().__init__()
        self.actor = actor_target
        object.__setattr__(self, "_reference", reference)  # not children: owned by the policy
        object.__setattr__(self, "_critic", critic_target)
        self.reference_share = 0.0

    def forward(self, obs: PyTorchObs) -> th.Tensor:
        proposals = self.actor(obs), self._reference(obs)
        chosen = choose(self._critic, obs, *proposals)
        self.reference_share = float((chosen == proposals[1]).all(dim=1).float().mean())
        return chosen


class ReferenceTD3Policy(LayerNormTD3Policy):
    """TD3's MultiInputPolicy (with LayerNorm, tsrl.agents.learners) plus a frozen `reference` actor the
    critic chooses against in acting and in the TD target (module docstring). The reference starts as
    the actor; tsrl.agents.bc.pretrain_actor sets both to the clone."""

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)
        self.reference = self.make_actor(features_extractor=None)
        self.reference.load_state_dict(self.actor.state_dict())
        self.reference.requires_grad_(False)
        self.reference.set_training_mode(False)
        # TD3 calls and polyak-updates its actor_target: a ChosenTarget is both (its parameters are the actor's)
        self.actor_target = ChosenTarget(self.actor_target, self.reference, self.critic_target)  # type: ignore[assignment]

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        return choose(self.critic, observation, self.actor(observation), self.reference(observation))
