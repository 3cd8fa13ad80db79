"""Ending an update early on a signal: before its next gradient step, not after all of them.

An update of an off-policy learner is many gradient steps (`gradient_steps`: utd x the env steps of
the episodes since the last one, 400 on the stack with the fast learner and 20,000 for a 10,000-step
episode), with no callback between them. `UpdateStop` puts a check before each: a step pre-hook of
the optimizer each gradient step steps first (SAC's and TQC's entropy coefficient's where it is
learned, behaviour cloning's actor's, else the critic's) raises `UpdateStopped` once `stopped()` is True, so the gradient step in
progress applies nothing and every earlier one is whole (TD3's delayed actor step and the target
update included). The rest of the update
is dropped. `settle()` then counts the gradient steps applied in `_n_updates`: TD3 counts a step
before it runs, SAC an update after it has run, BC a step after it; each is set to what was applied.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm

from .bc import BehaviourCloning


class UpdateStopped(Exception):
    """An update ended before its next gradient step (module docstring)."""


class UpdateStop:
    """The check before each gradient step of `model` (module docstring). `begin()` where an update
    is about to start (the callback's on_rollout_end); `settle()` after UpdateStopped."""

    def __init__(self, model: OffPolicyAlgorithm, stopped: Callable[[], bool]):
        self.model = model
        self.stopped = stopped
        self.begin()
        steps_first: Any = model.actor if isinstance(model, BehaviourCloning) else model.critic  # type: ignore[attr-defined]
        first = getattr(model, "ent_coef_optimizer", None) or steps_first.optimizer
        first.register_step_pre_hook(self._before_step)

    def begin(self) -> None:
        self.start, self.applied = self.model._n_updates, 0

    def _before_step(self, optimizer: Any, args: Any, kwargs: Any) -> None:
        if self.stopped():
            raise UpdateStopped
        self.applied += 1

    def settle(self) -> None:
        """`_n_updates`: the updates before this one plus its gradient steps applied."""
        self.model._n_updates = self.start + self.applied
