"""Behaviour cloning (BC): the actor regressed onto the demonstrated actions, with no env step.

`BehaviourCloning` is stable-baselines3's TD3 with its `learn` replaced: every gradient step draws a
batch of demonstration transitions (observation dict normalised as the run's VecNormalize does it),
and minimises the mean squared error between the actor's deterministic action (tanh output, in
[-1, 1]) and the demonstrated one with Adam. Its actor has dropout after each hidden layer (off when
it acts: SB3's predict and the export put the policy in eval mode). Being an SB3 algorithm with
TD3's policy, a BC run folder is evaluated, rendered, exported and resumed like any other; its
clock is gradient steps (`_n_updates`), its env steps stay 0. The critic TD3 builds is never trained.

`clone_step` is the one BC update; the fast learner pre-trains its actor with it (tsrl.agents.demos).

    L_BC = mean over the batch and action dimensions of (pi(s) - a_demo)^2
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np
import stable_baselines3.td3.policies as td3_policies
import torch as th
from stable_baselines3 import TD3
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize
from torch import nn
from torch.nn import functional as F

from ..envs.keys import OBS_KEYS
from .action_penalty import actor_action
from .demo_files import Demonstrations
from .own_draws import own_draws

FURTHER_CLONES_SEED = 104729
"""Added to the run's torch seed and a clone's index for the draws of a reference's clones beyond the
first (tsrl.agents.reference.CloneEnsemble): their initial weights and their BC batches."""


def with_dropout(mlp: nn.Sequential, p: float) -> nn.Sequential:
    """`mlp` (create_mlp's layers) with nn.Dropout(p) after each hidden activation (every ReLU)."""
    layers: list[nn.Module] = []
    for layer in mlp:
        layers.append(layer)
        if isinstance(layer, nn.ReLU) and p > 0:
            layers.append(nn.Dropout(p))
    return nn.Sequential(*layers)


class BCPolicy(td3_policies.MultiInputPolicy):
    """TD3's MultiInputPolicy whose actor has dropout `bc_dropout` after each hidden layer."""

    bc_dropout: float

    def __init__(self, *args: Any, bc_dropout: float = 0.1, **kwargs: Any):
        object.__setattr__(self, "bc_dropout", bc_dropout)  # before BasePolicy builds the networks
        super().__init__(*args, **kwargs)

    def make_actor(self, features_extractor: Any = None) -> Any:
        actor = super().make_actor(features_extractor)
        actor.mu = with_dropout(actor.mu, self.bc_dropout)
        return actor

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return super()._get_constructor_parameters() | {"bc_dropout": self.bc_dropout}


class DemoBatches:
    """The demonstration transitions as the actor sees them: (n, dim) normalised tensors per key and
    the (n, k) demonstrated actions; `sample` draws rows uniformly with the numpy global RNG (seeded by
    SB3's set_random_seed and restored on resume)."""

    def __init__(self, demos: Demonstrations, normalizer: VecNormalize | None):
        steps = slice(0, demos.episode_steps)  # the states the actions were taken in
        obs = {
            key: getattr(demos, key)[:, steps].reshape(-1, getattr(demos, key).shape[-1]) for key in OBS_KEYS
        }
        if normalizer is not None:
            normalised = normalizer.normalize_obs(obs)
            assert isinstance(normalised, dict)
            obs = normalised
        self.obs = {key: th.as_tensor(value, dtype=th.float32) for key, value in obs.items()}
        self.actions = th.as_tensor(demos.actions.reshape(-1, demos.actions.shape[-1]), dtype=th.float32)

    def __len__(self) -> int:
        return int(self.actions.shape[0])

    def sample(self, batch_size: int) -> tuple[dict[str, th.Tensor], th.Tensor]:
        rows = th.as_tensor(np.random.randint(0, len(self), size=batch_size))
        return {key: value[rows] for key, value in self.obs.items()}, self.actions[rows]


def clone_step(
    act: Callable[[dict[str, th.Tensor]], th.Tensor],
    optimizer: th.optim.Optimizer,
    obs: dict[str, th.Tensor],
    actions: th.Tensor,
) -> float:
    """One BC gradient step: `act` maps a batch of normalised observations to (n, k) deterministic
    actions (an SB3 actor in training mode); `optimizer` steps its parameters. Returns the loss."""
    loss = F.mse_loss(act(obs), actions)
    optimizer.zero_grad()
    loss.backward()
    optimizer.step()
    return float(loss.item())


def _train_clone(
    clone: Any,
    optimizer: th.optim.Optimizer,
    act: Callable[[dict[str, th.Tensor]], th.Tensor],
    batches: DemoBatches,
    steps: int,
    batch_size: int,
) -> None:
    """`steps` BC steps of `clone` (an SB3 actor) in training mode; it ends frozen, dropout off."""
    clone.requires_grad_(True)
    clone.set_training_mode(True)
    for _ in range(steps):
        clone_step(act, optimizer, *batches.sample(batch_size))
    clone.set_training_mode(False)
    clone.requires_grad_(False)


def _clone_alone(
    model: OffPolicyAlgorithm, clone: Any, batches: DemoBatches, steps: int, batch_size: int
) -> None:
    """A reference's clone trained as a BC run trains its actor: with its dropout and a fresh Adam at
    the actor's learning rate."""
    optimizer = th.optim.Adam(clone.parameters(), lr=model.lr_schedule(1), foreach=True)
    _train_clone(clone, optimizer, clone, batches, steps, batch_size)


def pretrain_actor(model: OffPolicyAlgorithm, batches: DemoBatches, steps: int, batch_size: int) -> None:
    """`steps` BC gradient steps before any env step. With a reference (tsrl.agents.reference) the
    clone is trained as a BC run trains its actor: the reference, with its dropout, and a fresh Adam at
    the actor's learning rate; the actor and the target actor are then copied from it (a residual actor
    is not: it starts as the clone by construction). Without one,
    the actor (its deterministic action, its own optimizer), then copied into the target actor. A
    CloneEnsemble reference trains each clone so, the first from the run's draws and the others from
    their own (FURTHER_CLONES_SEED), and the actors start as the first."""
    policy: Any = model.policy
    reference = getattr(policy, "reference", None)
    clone: Any = model.actor if reference is None else reference  # type: ignore[attr-defined]
    members = getattr(clone, "members", None)  # a CloneEnsemble's clones, each trained alone
    if members is not None:
        _clone_alone(model, members[0], batches, steps, batch_size)
        for index, member in enumerate(members[1:], start=1):  # from their own draws: the run's stay
            with own_draws(FURTHER_CLONES_SEED + index):
                _clone_alone(model, member, batches, steps, batch_size)
        clone = members[0]  # the actor starts as the first clone
    elif reference is None:
        optimizer, act = clone.optimizer, partial(actor_action, model)
        _train_clone(clone, optimizer, act, batches, steps, batch_size)
        clone.requires_grad_(True)  # the actor trains on
    else:
        _clone_alone(model, clone, batches, steps, batch_size)
    # a residual actor (tsrl.agents.reference) starts at zero on the clone: only the reference is a copy
    copies: tuple[str, ...] = ("actor", "actor_target", "reference")
    if getattr(policy, "residual", 0) > 0:
        copies = ("reference",)
    elif members is not None:  # the ensemble is the reference; the actors copy its first clone
        copies = ("actor", "actor_target")
    for name in copies:
        copy = getattr(policy, name, None)
        if copy is not None and copy is not clone:  # parameter by parameter: layers differ by dropout
            with th.no_grad():
                for to, source in zip(copy.parameters(), clone.parameters(), strict=True):
                    to.copy_(source)


class BehaviourCloning(TD3):
    """TD3's networks trained by behaviour cloning only (module docstring); `set_demos` before `learn`.

    `learn(n)` runs n more gradient steps (as SB3's learn runs n more env steps), calling the callback's
    on_rollout_start every `chunk` steps (tsrl.agents.training's safe points: evaluation, checkpoint,
    a stop on a signal) and its on_training_end at the end.
    """

    chunk = 100
    """Gradient steps between two calls of the callback's on_rollout_start."""

    def set_demos(self, demos: Demonstrations, normalizer: VecNormalize | None) -> None:
        self.batches = DemoBatches(demos, normalizer)

    def _excluded_save_params(self) -> list[str]:
        return [*super()._excluded_save_params(), "batches"]

    def learn(  # type: ignore[override]
        self,
        total_timesteps: int,
        callback: BaseCallback | None = None,
        log_interval: int = 4,
        tb_log_name: str = "bc",
        reset_num_timesteps: bool = False,
        progress_bar: bool = False,
    ) -> BehaviourCloning:
        """`total_timesteps` more gradient steps (a BC run's budget is bc_steps gradient steps)."""
        end = self._n_updates + total_timesteps
        _, cb = self._setup_learn(0, callback, reset_num_timesteps, tb_log_name, progress_bar)
        cb.on_training_start(locals(), globals())
        actor = self.actor
        loss = float("nan")
        while self._n_updates < end:
            cb.on_rollout_start()
            actor.set_training_mode(True)  # an evaluation at the safe point put it in eval mode
            for _ in range(min(self.chunk, end - self._n_updates)):
                loss = clone_step(actor, actor.optimizer, *self.batches.sample(self.batch_size))
                self._n_updates += 1
            self.logger.record("train/bc_loss", loss)
            self.logger.record("train/actor_loss", loss)
            self.logger.record("train/n_updates", self._n_updates)
        actor.set_training_mode(False)
        cb.on_training_end()
        return self
