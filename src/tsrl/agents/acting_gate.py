"""Which policy the fast learner acts with when it acts deterministically: its clone, or the choice
between clone and actor (tsrl.agents.reference), decided by episodes measured on the task itself.

The critic's choice can be wrong where it is sure (both heads over-valuing the actor's action: the
actor is trained to maximise them), so the deterministic policy (evaluation, export, deployment) does
not rest on it alone. Training episodes cycle through four kinds:

    explore (the choice plus TD3's noise), choice (no noise), explore, clone (no noise)

and the success of the last `WINDOW` episodes of each measured kind (the last step's
info["is_success"], as evaluation counts it) decides: the choice acts where its measured success is
strictly above the clone's, each measured on at least `MIN_EPISODES`, else the clone. The clone is
frozen (and the observation normaliser with it), so it is measured once: after its first `WINDOW`
episodes its place in the cycle explores. Every episode is training data. `GatedTD3` is TD3 with the
episode kinds (`_sample_action`) and the bookkeeping at episode ends (`_store_transition`); the
decision is the policy's `choice_acts` buffer, so a saved policy acts as decided when loaded without
its algorithm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from stable_baselines3 import TD3
from stable_baselines3.common.noise import ActionNoise

from .reference import CHOICE, CLONE, ReferenceTD3Policy

EPISODE_KINDS = ("explore", CHOICE, "explore", CLONE)
WINDOW = 20
"""Measured episodes of each kind compared (the latest)."""
MIN_EPISODES = 10
"""Measured episodes each kind needs before the choice may act."""


@dataclass
class ActingGate:
    """The episode kinds' cycle and the measured successes (module docstring)."""

    episodes: int = 0
    """Training episodes ended."""
    measured: dict[str, list[bool]] = field(default_factory=lambda: {CHOICE: [], CLONE: []})

    @property
    def kind(self) -> str:
        """The kind of the episode under way."""
        kind = EPISODE_KINDS[self.episodes % len(EPISODE_KINDS)]
        return "explore" if kind == CLONE and len(self.measured[CLONE]) == WINDOW else kind

    def end_episode(self, success: bool) -> None:
        if self.kind in self.measured:
            self.measured[self.kind] = [*self.measured[self.kind], success][-WINDOW:]
        self.episodes += 1

    def success(self, kind: str) -> float:
        """Measured success of `kind` over its window (nan before its first episode)."""
        window = self.measured[kind]
        return float(np.mean(window)) if window else float("nan")

    @property
    def choice_acts(self) -> bool:
        choice, clone = self.measured[CHOICE], self.measured[CLONE]
        if min(len(choice), len(clone)) < MIN_EPISODES:
            return False
        return self.success(CHOICE) > self.success(CLONE)


class GatedTD3(TD3):
    """TD3 whose policy is a ReferenceTD3Policy acting by the gate (module docstring); one env."""

    policy: ReferenceTD3Policy

    def __init__(self, *args: Any, **kwargs: Any):
        self.gate = ActingGate()  # before TD3 builds the policy; a loaded model's comes with its data
        super().__init__(*args, **kwargs)

    def _sample_action(
        self, learning_starts: int, action_noise: ActionNoise | None = None, n_envs: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        kind = self.gate.kind
        self.policy.episode_policy = CLONE if kind == CLONE else CHOICE
        try:
            return super()._sample_action(
                learning_starts, action_noise if kind == "explore" else None, n_envs
            )
        finally:
            self.policy.episode_policy = None

    def _store_transition(
        self,
        replay_buffer: Any,
        buffer_action: np.ndarray,
        new_obs: Any,
        reward: np.ndarray,
        dones: np.ndarray,
        infos: list[dict[str, Any]],
    ) -> None:
        super()._store_transition(replay_buffer, buffer_action, new_obs, reward, dones, infos)
        assert len(dones) == 1, "GatedTD3 trains on one env"
        if dones[0]:
            self.gate.end_episode(bool(infos[0].get("is_success", False)))
            self.policy.choice_acts.fill_(self.gate.choice_acts)
            self.logger.record("gate/choice_success", self.gate.success(CHOICE))
            self.logger.record("gate/clone_success", self.gate.success(CLONE))
            self.logger.record("gate/choice_acts", float(self.gate.choice_acts))
