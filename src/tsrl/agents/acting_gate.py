"""Which policy the fast learner acts with when it acts deterministically: its clone, or the choice
between clone and actor (tsrl.agents.reference), decided by episodes measured on the task itself.

The critic's choice can be wrong where it is sure (both heads over-valuing the actor's action: the
actor is trained to maximise them), so the deterministic policy (evaluation, export, deployment) does
not rest on it alone. Training episodes cycle through four kinds:

    explore (the choice plus TD3's noise), choice (no noise), explore, clone (no noise)

and measured success (the last step's info["is_success"], as evaluation counts it) decides: the
choice acts where the success of its last `WINDOW` episodes is strictly above the clone's, each
measured on at least `MIN_EPISODES`, else the clone. The clone is frozen (and the observation
normaliser with it), so it is measured once, on its first `clone_episodes` (AgentConfig.
clone_episodes; by default as many as `WINDOW`), all of which count: after them its place in the
cycle explores. Every episode is training data; one started from a
demonstration's state (tsrl.agents.demo_resets) is neither measured nor counted in the cycle, so the
gate compares the policies from the task's own starts, where evaluation runs them. `GatedTD3` is TD3 with the
episode kinds (`_sample_action`) and the bookkeeping at episode ends (`_store_transition`); the
decision is the policy's `choice_acts` buffer, so a saved policy acts as decided when loaded without
its algorithm.

With `adapt_noise` on, the explore episodes' success is measured too, and the scale of their noise
(of AgentConfig.action_noise) adapts to keep them winnable (as parameter-space noise adapts its scale
to a target, Plappert et al. 2018): once the last `WINDOW` explore episodes' success is below
`NOISE_DOWN` times the choice's, the scale halves (down to `NOISE_FLOOR`); at or above `NOISE_UP`
times it, it doubles (up to 1); each change starts a new window. On the stack the preset's noise
(std 0.1) takes the clone from 0.66 to 0.07 (studies/learner-from-demos, probe_noise.py), so three
quarters of its own episodes were failures made by the noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from stable_baselines3 import TD3
from stable_baselines3.common.noise import ActionNoise

from .config import CLONE_EPISODES, MIN_EPISODES
from .demo_resets import DEMO_RESET
from .reference import CHOICE, CLONE, ReferenceTD3Policy

EXPLORE = "explore"
"""The episodes that act by the choice plus the (scaled) noise."""
EPISODE_KINDS = (EXPLORE, CHOICE, EXPLORE, CLONE)
WINDOW = 20
"""Measured episodes of each kind compared (the latest)."""
NOISE_DOWN = 0.75
"""The explore episodes' success, as a share of the choice's, below which the noise halves."""
NOISE_UP = 0.95
"""The share at or above which the noise doubles (up to its configured std)."""
NOISE_FLOOR = 1 / 16
"""The smallest scale of the noise."""


@dataclass
class ActingGate:
    """The episode kinds' cycle and the measured successes (module docstring)."""

    episodes: int = 0
    """Training episodes ended."""
    measured: dict[str, list[bool]] = field(default_factory=lambda: {CHOICE: [], CLONE: []})
    clone_episodes: int = CLONE_EPISODES
    """The clone's episodes measured (all of them count) before its place in the cycle explores."""
    adapt_noise: bool = False
    """Measure the explore episodes and adapt their noise's scale (module docstring)."""
    noise_scale: float = 1.0
    """The explore episodes' noise as a share of its configured std."""

    @property
    def kind(self) -> str:
        """The kind of the episode under way."""
        kind = EPISODE_KINDS[self.episodes % len(EPISODE_KINDS)]
        return EXPLORE if kind == CLONE and len(self.measured[CLONE]) >= self.clone_episodes else kind

    def end_episode(self, success: bool) -> None:
        kind = self.kind
        if kind in self.measured or (kind == EXPLORE and self.adapt_noise):
            window = self.clone_episodes if kind == CLONE else WINDOW
            self.measured[kind] = [*self.measured.get(kind, []), success][-window:]
        if kind == EXPLORE and self.adapt_noise:
            self._adapt_noise()
        self.episodes += 1

    def _adapt_noise(self) -> None:
        explore, choice = self.measured[EXPLORE], self.measured[CHOICE]
        if len(explore) < WINDOW or len(choice) < MIN_EPISODES or not any(choice):
            return
        share = self.success(EXPLORE) / self.success(CHOICE)
        if share < NOISE_DOWN and self.noise_scale > NOISE_FLOOR:
            self.noise_scale /= 2
        elif share >= NOISE_UP and self.noise_scale < 1:
            self.noise_scale *= 2
        else:
            return
        self.measured[EXPLORE] = []  # judged again at the new scale

    def success(self, kind: str) -> float:
        """Measured success of `kind` over its window, the clone's over all its measured episodes (nan
        before the first)."""
        window = self.measured.get(kind, [])
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
        noise = action_noise if kind == EXPLORE else None
        if noise is not None and self.gate.adapt_noise:
            noise = ScaledNoise(noise, self.gate.noise_scale)
        try:
            return super()._sample_action(learning_starts, noise, n_envs)
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
        if dones[0] and DEMO_RESET not in infos[0]:  # measured from the task's own starts only
            self.gate.end_episode(bool(infos[0].get("is_success", False)))
            self.policy.choice_acts.fill_(self.gate.choice_acts)
            self.logger.record("gate/choice_success", self.gate.success(CHOICE))
            self.logger.record("gate/clone_success", self.gate.success(CLONE))
            self.logger.record("gate/choice_acts", float(self.gate.choice_acts))
            if self.gate.adapt_noise:
                self.logger.record("gate/explore_success", self.gate.success(EXPLORE))
                self.logger.record("gate/noise_scale", self.gate.noise_scale)


class ScaledNoise(ActionNoise):
    """`noise`'s draws times `scale` (the same random numbers)."""

    def __init__(self, noise: ActionNoise, scale: float):
        super().__init__()
        self.noise, self.scale = noise, scale

    def __call__(self) -> np.ndarray:
        return self.scale * self.noise()

    def reset(self) -> None:
        self.noise.reset()
