"""A loss added to an algorithm's own at one of its optimizers, without copying any `train()`.

stable-baselines3 runs `zero_grad(); loss.backward(); step()` for each network; a step pre-hook
registered on that optimizer back-propagates `weight * L` on the replay buffer's batch of the same
gradient step (`last_batch`) before the step, so the step follows grad(loss + weight * L). The
action penalty, the return bound and the choice's distillation are such losses (the BC loss of
tsrl.agents.demos too, which also rescales the gradient before it).
"""

from __future__ import annotations

from typing import Any

import torch as th
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm


class AddedLoss:
    """Step pre-hook: back-propagates weight * `loss(batch)` on the buffer's last batch, where there is
    one and `loss` gives a value, and records its named values in the model's logger as train/NAME
    (the latest gradient step's)."""

    def __init__(self, model: OffPolicyAlgorithm, weight: float):
        self.model = model
        self.weight = weight

    def loss(self, batch: Any) -> tuple[th.Tensor, dict[str, float]] | None:
        """(L, values to record) on the gradient step's batch, with the gradient on; None: nothing."""
        raise NotImplementedError

    def __call__(self, optimizer: th.optim.Optimizer, args: Any, kwargs: Any) -> None:
        batch = getattr(self.model.replay_buffer, "last_batch", None)
        if batch is None:
            return
        with th.enable_grad():
            result = self.loss(batch)
            if result is None:
                return
            loss, values = result
            (self.weight * loss).backward()
        for name, value in values.items():
            self.model.logger.record(f"train/{name}", value)
