"""Which policy the fast learner acts with when it acts deterministically: the clone, or the best
snapshot of its choice between clone and actor (tsrl.agents.reference) measured so far, decided by
episodes measured on the task itself.

The critic's choice can be wrong where it is sure (both heads over-valuing the actor's action: the
actor is trained to maximise them), and the learning actor can drift below where it was, so the
deterministic policy (evaluation, export, deployment) is never the learning choice: it is the *kept*
policy, the clone until a frozen snapshot of the choice measures better. Training episodes cycle
through four kinds:

    explore (the learning choice plus TD3's noise), candidate, explore, kept

- a *candidate* episode acts with the candidate snapshot, without noise: the learning actor and critic
  copied at the start of its first episode, frozen while it is measured;
- a *kept* episode acts with the deterministic policy, without noise, for the first `KEPT_EPISODES`
  after a policy is kept (the clone first); after them that place in the cycle explores.

After each candidate episode, a sequential test on the measured successes (the last step's
info["is_success"], as evaluation counts it): with uniform priors on the two success rates, the
posterior probability `prob_better` that the candidate's rate is above the kept policy's. The
candidate is kept (it acts from then on, its measured episodes with it) where that probability is at
least `KEEP` after `MIN_TO_KEEP` of its episodes, and dropped where it is at most `DROP` after
`MIN_TO_DROP`, or after `MAX_CANDIDATE` episodes undecided; the next candidate episode takes a new
snapshot. So the deterministic policy changes only to a policy measured better than itself, never
back. Every episode is training data. `GatedTD3` is TD3 with the episode kinds (`_sample_action`) and
the bookkeeping at episode ends (`_store_transition`); the decision is in the policy (its `kept`
snapshot and `choice_acts` buffer), so a saved policy acts as decided when loaded without its
algorithm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import betaln
from stable_baselines3 import TD3
from stable_baselines3.common.noise import ActionNoise

from .reference import CANDIDATE, EXPLORE, KEPT, ReferenceTD3Policy

EPISODE_KINDS = (EXPLORE, CANDIDATE, EXPLORE, KEPT)
KEPT_EPISODES = 20
"""Episodes of a newly kept policy measured in its place in the cycle."""
KEEP = 0.9
"""Posterior probability of a higher success rate at which a candidate is kept."""
DROP = 0.2
"""Posterior probability of a higher success rate at or below which a candidate is dropped."""
MIN_TO_KEEP = 10
"""Measured episodes a candidate (and the kept policy) needs before it may be kept."""
MIN_TO_DROP = 5
"""Measured episodes a candidate (and the kept policy) needs before it may be dropped."""
MAX_CANDIDATE = 40
"""Measured episodes after which an undecided candidate is dropped (the kept policy stays)."""


def prob_better(a: list[bool], b: list[bool]) -> float:
    """P(p_a > p_b) for the success rates of two measured policies, each with a uniform prior:
    p_a ~ Beta(1 + successes, 1 + failures) and p_b likewise, independent (an exact finite sum)."""
    a1, b1 = 1 + sum(a), 1 + len(a) - sum(a)
    a2, b2 = 1 + sum(b), 1 + len(b) - sum(b)
    i = np.arange(a1)
    terms = betaln(a2 + i, b1 + b2) - np.log(b1 + i) - betaln(1 + i, b1) - betaln(a2, b2)
    return float(np.exp(terms).sum())


@dataclass
class ActingGate:
    """The episode kinds' cycle and the measured successes (module docstring)."""

    episodes: int = 0
    """Training episodes ended."""
    kept: list[bool] = field(default_factory=list)
    """Measured episodes of the kept policy (a kept candidate's come with it)."""
    kept_episodes: int = 0
    """Episodes of the kept policy measured in its place in the cycle since it was kept."""
    candidate: list[bool] | None = None
    """Measured episodes of the candidate; None: the next candidate episode takes a new snapshot."""
    snapshots_kept: int = 0
    """Candidates kept so far (0: the clone acts)."""

    @property
    def kind(self) -> str:
        """The kind of the episode under way."""
        kind = EPISODE_KINDS[self.episodes % len(EPISODE_KINDS)]
        return EXPLORE if kind == KEPT and self.kept_episodes >= KEPT_EPISODES else kind

    def end_episode(self, success: bool) -> None:
        kind = self.kind
        self.episodes += 1
        if kind == KEPT:
            self.kept.append(success)
            self.kept_episodes += 1
        elif kind == CANDIDATE:
            assert self.candidate is not None, "a candidate episode starts by taking a snapshot"
            self.candidate.append(success)
            verdict = self.verdict()
            if verdict == KEPT:
                self.kept, self.kept_episodes = self.candidate, 0
                self.snapshots_kept += 1
            if verdict is not None:
                self.candidate = None

    def verdict(self) -> str | None:
        """KEPT (keep the candidate), "dropped", or None (measure on): the sequential test."""
        candidate = self.candidate or []
        measured = min(len(candidate), len(self.kept))
        if measured < MIN_TO_DROP:
            return None
        better = prob_better(candidate, self.kept)
        if measured >= MIN_TO_KEEP and better >= KEEP:
            return KEPT
        if better <= DROP or len(candidate) >= MAX_CANDIDATE:
            return "dropped"
        return None

    @property
    def choice_acts(self) -> bool:
        """A snapshot of the choice is the kept policy (else the clone)."""
        return self.snapshots_kept > 0

    def success(self, measured: list[bool] | None) -> float:
        """Measured success (nan before the first episode)."""
        return float(np.mean(measured)) if measured else float("nan")


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
        if kind == CANDIDATE and self.gate.candidate is None:  # a new candidate: the learning choice now
            self.policy.candidate.take(self.policy.actor, self.policy.critic)
            self.gate.candidate = []
        self.policy.episode_policy = None if kind == KEPT else kind
        try:
            return super()._sample_action(learning_starts, action_noise if kind == EXPLORE else None, n_envs)
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
            kept = self.gate.snapshots_kept
            self.gate.end_episode(bool(infos[0].get("is_success", False)))
            if self.gate.snapshots_kept > kept:  # the candidate measured better: it acts from now on
                self.policy.kept.load_state_dict(self.policy.candidate.state_dict())
            self.policy.choice_acts.fill_(self.gate.choice_acts)
            self.logger.record("gate/kept_success", self.gate.success(self.gate.kept))
            self.logger.record("gate/candidate_success", self.gate.success(self.gate.candidate))
            self.logger.record("gate/snapshots_kept", self.gate.snapshots_kept)
