"""A frozen reference policy beside the actor, the critic choosing between them (IBRL, Hu et al. 2023).

The fast learner's policy keeps its behaviour clone frozen (`reference`), trained as a BC run trains
its actor (tsrl.agents.bc: dropout after each hidden layer, off when it acts). Wherever TD3 takes the
actor's action, it takes instead, per row, the proposal the critic's smaller twin head values more
(IBRL's argmax over the proposals, with TD3's clipped double-Q estimate):

    a(s) = reference(s) if min_i Q_i(s, reference(s)) > min_i Q_i(s, actor(s)) else actor(s)

- acting and evaluation (the policy's `_predict`, and so the export): the critic's twin heads;
- the TD target (TD3's `actor_target`): the target critic's twin heads on the target actor's and the
  reference's proposals, before TD3's target smoothing noise is added to the chosen one.

The critic can be sure and wrong about the actor's action on the steps that decide an episode, so
whether this choice or the clone alone is the policy's deterministic action is decided by measured
episodes (tsrl.agents.acting_gate; the `choice_acts` buffer). The actor's own loss is TD3's (with the
BC anchor of tsrl.agents.demos).

With `residual` alpha > 0 the actor is a bounded correction of the clone instead of a second policy
(residual policy learning, Silver et al. 2018; on imitation policies, Yuan et al. 2024's Policy
Decorator): its action is clamp(reference(s) + alpha * r(s), -1, 1) with r the actor's own tanh
network, started at zero, so the actor begins as the clone and can move each action component by at
most alpha (in the action's [-1, 1] units) from it. The actor's optimizer steps r only.
With `clone_proposals` K > 0 the critic chooses among K + 2 proposals: the actor's, the clone's and
those of K thinned clones, the clone with K fixed dropout masks (drawn once from THINNING_SEED, the
same in every run; MC dropout's sub-networks): a best of N over samples of the behaviour model, as
EMaQ (Ghasemipour et al. 2021) takes, with the actor's proposal first so that it keeps ties.

With `clones` C > 1 the reference is `CloneEnsemble`: the mean action of C clones of the same
demonstrations, each trained as BC trains its actor (tsrl.agents.bc.pretrain_actor), the first from
the run's own draws (the clone of the run without it, which the actor starts as) and the others from
their own generators (seeded from the run's seed). Averaging clones cuts BC's seed-to-seed spread:
on the stack five clones' mean action scored 0.69 against 0.44-0.63 for each alone (pre-registration
25 of studies/learner-from-demos).

`ReferenceTD3Policy` is a module-level class, so saved models load with it; the reference (and the
thinned clones' masks) are part of the policy's state dict (checkpoints keep them).
"""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.type_aliases import PyTorchObs
from stable_baselines3.td3.policies import Actor
from torch import nn

from .bc import FURTHER_CLONES_SEED, with_dropout
from .learners import LayerNormTD3Policy
from .own_draws import own_draws

CHOICE = "choice"
"""The policy that acts by `choose` between actor and clone."""
CLONE = "clone"
"""The policy that acts by the clone alone."""
THINNING_SEED = 0
"""Seed of the generator that draws the thinned clones' dropout masks (the same masks in every run)."""


class CloneEnsemble(nn.Module):
    """The reference as the mean action of C clones (module docstring): obs -> (n, k). `members` are
    SB3 Actors with dropout, each trained alone (tsrl.agents.bc.pretrain_actor)."""

    def __init__(self, members: list[Actor]):
        super().__init__()
        self.members = nn.ModuleList(members)

    def forward(self, obs: PyTorchObs) -> th.Tensor:
        return th.stack([member(obs) for member in self.members]).mean(dim=0)

    def set_training_mode(self, mode: bool) -> None:
        for member in self.members:
            member.set_training_mode(mode)  # type: ignore[operator]


def heads(critic: nn.Module, obs: PyTorchObs, actions: th.Tensor) -> th.Tensor:
    """(n, heads) the critic's values (SB3's ContinuousCritic: a tuple of (n, 1), one per head)."""
    return th.cat(critic(obs, actions), dim=1)


def reference_preferred(
    critic: nn.Module, obs: PyTorchObs, actor_actions: th.Tensor, reference_actions: th.Tensor
) -> th.Tensor:
    """(n, 1) bool: per row, the smaller of the critic's heads strictly higher for the reference's
    action than for the actor's (the choice's rule)."""
    actor_low = heads(critic, obs, actor_actions).min(dim=1, keepdim=True).values
    reference_low = heads(critic, obs, reference_actions).min(dim=1, keepdim=True).values
    return reference_low > actor_low


def choose(
    critic: nn.Module, obs: PyTorchObs, actor_actions: th.Tensor, reference_actions: th.Tensor
) -> th.Tensor:
    """(n, k): per row, the reference's action where it is preferred (reference_preferred), else the
    actor's."""
    return th.where(
        reference_preferred(critic, obs, actor_actions, reference_actions), reference_actions, actor_actions
    )


def choose_among(critic: nn.Module, obs: PyTorchObs, proposals: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
    """The choice's rule over P proposals (P, n, k): per row, the proposal whose smaller critic head is
    highest, the first of the highest where they tie. Returns the chosen actions (n, k) and their
    proposal indices (n,)."""
    count, n, k = proposals.shape
    if isinstance(obs, dict):
        repeated: PyTorchObs = {
            key: value.repeat(count, *([1] * (value.dim() - 1))) for key, value in obs.items()
        }
    else:
        repeated = obs.repeat(count, *([1] * (obs.dim() - 1)))
    low = heads(critic, repeated, proposals.reshape(count * n, k)).min(dim=1).values.reshape(count, n)
    index = low.argmax(dim=0)  # the first maximum: the actor's (proposal 0) on ties
    chosen = proposals.gather(0, index.view(1, n, 1).expand(1, n, k)).squeeze(0)
    return chosen, index


class ThinnedClones(nn.Module):
    """K fixed thinned copies of the reference (module docstring): obs -> (K, n, k), the reference with
    dropout mask j (kept units scaled by 1 / (1 - p), as dropout trains them) for copy j. The masks are
    buffers (`mask0`, `mask1`, ...: (K, h) per dropout layer of the reference's mu), drawn at
    construction from THINNING_SEED; the reference is not a child (the policy owns it)."""

    _reference: Actor

    def __init__(self, reference: Actor, count: int, p: float):
        super().__init__()
        object.__setattr__(self, "_reference", reference)
        self.count = count
        widths, width = [], 0  # per dropout layer, the width of the Linear before it
        for layer in reference.mu:
            if isinstance(layer, nn.Linear):
                width = layer.out_features
            elif isinstance(layer, nn.Dropout):
                widths.append(width)
        if not widths:
            raise ValueError("clone proposals need a reference with dropout (bc_dropout > 0)")
        generator = th.Generator().manual_seed(THINNING_SEED)
        for i, width in enumerate(widths):
            keep = th.bernoulli(th.full((count, width), 1.0 - p), generator=generator) / (1.0 - p)
            self.register_buffer(f"mask{i}", keep)
        self.layers = len(widths)

    def forward(self, obs: PyTorchObs) -> th.Tensor:
        reference = self._reference
        features = reference.extract_features(obs, reference.features_extractor)
        x = features.unsqueeze(0).expand(self.count, *features.shape)
        masks = iter(getattr(self, f"mask{i}") for i in range(self.layers))
        for layer in reference.mu:
            x = x * next(masks).unsqueeze(1) if isinstance(layer, nn.Dropout) else layer(x)
        return x

    def beside(self, actor_actions: th.Tensor, reference_actions: th.Tensor, obs: PyTorchObs) -> th.Tensor:
        """(K + 2, n, k) the choice's proposals: the actor's and the reference's actions (n, k), then
        the thinned clones' on `obs`."""
        return th.cat((th.stack((actor_actions, reference_actions)), self(obs)))


class ChosenTarget(nn.Module):
    """TD3's target actor whose action is the choice (module docstring) between its own proposal and the
    reference's, valued by the target critic. Only the target actor is a registered child: its
    parameters are TD3's polyak targets, and the reference and critic stay where the policy keeps them.
    `reference_share` is the share of rows the reference (or, with `thinned`, any clone) won in the
    last call."""

    _reference: nn.Module
    _critic: nn.Module
    _thinned: ThinnedClones | None

    def __init__(
        self,
        actor_target: nn.Module,
        reference: nn.Module,
        critic_target: nn.Module,
        thinned: ThinnedClones | None = None,
    ):
        super().__init__()
        self.actor = actor_target
        object.__setattr__(self, "_reference", reference)  # not children: owned by the policy
        object.__setattr__(self, "_critic", critic_target)
        object.__setattr__(self, "_thinned", thinned)
        self.reference_share = 0.0

    def forward(self, obs: PyTorchObs) -> th.Tensor:
        if self._thinned is not None:  # among all proposals; the clone's or a thinned clone's won
            ranked = self._thinned.beside(self.actor(obs), self._reference(obs), obs)
            chosen, index = choose_among(self._critic, obs, ranked)
            self.reference_share = float((index > 0).float().mean())
            return chosen
        proposals = self.actor(obs), self._reference(obs)
        chosen = choose(self._critic, obs, *proposals)
        self.reference_share = float((chosen == proposals[1]).all(dim=1).float().mean())
        return chosen


class ResidualHead(nn.Module):
    """An actor's `mu` as a bounded residual on the reference's (module docstring): features (n, d) ->
    (n, k) clamp(reference_mu(f) + scale * residual(f), -1, 1). Only `residual` is a registered child
    (the actor's parameters and optimizer); its last Linear starts at zero, so the head starts as the
    reference. Both nets read the same features (the policy's inputs, tsrl.agents.learners)."""

    _reference: nn.Module

    def __init__(self, residual: nn.Sequential, reference: nn.Module, scale: float):
        super().__init__()
        self.residual = residual
        object.__setattr__(self, "_reference", reference)  # not a child: the policy's frozen clone
        self.scale = scale
        last = [m for m in residual.modules() if isinstance(m, nn.Linear)][-1]
        with th.no_grad():
            last.weight.zero_()
            last.bias.zero_()

    def forward(self, features: th.Tensor) -> th.Tensor:
        return th.clamp(self._reference(features) + self.scale * self.residual(features), -1.0, 1.0)


class ReferenceTD3Policy(LayerNormTD3Policy):
    """TD3's MultiInputPolicy (with LayerNorm, tsrl.agents.learners) plus a frozen `reference` actor with
    dropout `reference_dropout` after each hidden layer (as BC's), which the critic chooses against in
    acting and in the TD target (module docstring). The reference starts as the actor;
    tsrl.agents.bc.pretrain_actor clones the demonstrations into it and copies it into the actors.

    With `residual` > 0 the actor and its target are ResidualHeads on the reference (module
    docstring). It acts by the choice where the `choice_acts` buffer (a () bool tensor, in the state dict) is
    True, else by the clone alone; `episode_policy` (CHOICE or CLONE), where set, overrides it for a
    training episode (tsrl.agents.acting_gate)."""

    reference_dropout: float
    residual: float
    clone_proposals: int
    clones: int
    choice_acts: th.Tensor
    episode_policy: str | None = None
    thinned: ThinnedClones | None

    def __init__(
        self,
        *args: Any,
        reference_dropout: float = 0.1,
        residual: float = 0.0,
        clone_proposals: int = 0,
        clones: int = 1,
        **kwargs: Any,
    ):
        object.__setattr__(self, "reference_dropout", reference_dropout)  # before _build runs
        object.__setattr__(self, "residual", residual)
        object.__setattr__(self, "clone_proposals", clone_proposals)
        object.__setattr__(self, "clones", clones)
        super().__init__(*args, **kwargs)

    def _make_clone(self) -> Actor:
        clone = self.make_actor(features_extractor=None)
        clone.mu = with_dropout(clone.mu, self.reference_dropout)
        return clone

    def _build(self, lr_schedule: Any) -> None:
        super()._build(lr_schedule)
        first = self._make_clone()
        with th.no_grad():
            for to, source in zip(first.parameters(), self.actor.parameters(), strict=True):
                to.copy_(source)
        self.reference: Actor | CloneEnsemble = first
        if self.clones > 1:  # the further clones from their own draws: every other network's stay
            members = [first]
            for index in range(1, self.clones):
                with own_draws(FURTHER_CLONES_SEED + index):
                    members.append(self._make_clone())
            self.reference = CloneEnsemble(members)
        self.reference.requires_grad_(False)
        self.reference.set_training_mode(False)
        self.register_buffer("choice_acts", th.tensor(False))
        if self.residual > 0:  # the actor's own network becomes the residual (the same parameters)
            for actor in (self.actor, self.actor_target):
                actor.mu = ResidualHead(actor.mu, first.mu, self.residual)  # type: ignore[assignment]
        self.thinned = None
        if self.clone_proposals > 0:  # masks from their own generator: the networks' draws stay as without
            self.thinned = ThinnedClones(first, self.clone_proposals, self.reference_dropout)
        # TD3 calls and polyak-updates its actor_target: a ChosenTarget is both (its parameters are the actor's)
        self.actor_target = ChosenTarget(self.actor_target, self.reference, self.critic_target, self.thinned)  # type: ignore[assignment]

    def set_training_mode(self, mode: bool) -> None:
        """TD3's, with the reference always acting as it does once cloned (dropout off)."""
        super().set_training_mode(mode)
        self.reference.set_training_mode(False)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return super()._get_constructor_parameters() | {
            "reference_dropout": self.reference_dropout,
            "residual": self.residual,
            "clone_proposals": self.clone_proposals,
            "clones": self.clones,
        }

    def _predict(self, observation: PyTorchObs, deterministic: bool = False) -> th.Tensor:
        clone = self.reference(observation)
        if self.episode_policy == CLONE:
            return clone
        if self.thinned is not None:  # among the actor, the clone and the thinned clones
            proposals = self.thinned.beside(self.actor(observation), clone, observation)
            chosen = choose_among(self.critic, observation, proposals)[0]
        else:
            chosen = choose(self.critic, observation, self.actor(observation), clone)
        if self.episode_policy == CHOICE:
            return chosen
        return th.where(self.choice_acts, chosen, clone)  # a tensor, not a Python branch: exports as such
