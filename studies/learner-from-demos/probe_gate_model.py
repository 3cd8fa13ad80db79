"""A simulation of acting gates on model learning curves (README, pre-registration 7's withdrawal): how
often each gate's evaluations meet a task's target, with no network trained.

A model curve gives the true success of the learner's choice at each training episode (its snapshot
at that episode); measured episodes are Bernoulli draws of it; an evaluation is 100 draws of the
deterministic policy's true success. Two gates:

- `igate`: pre-registration 6 (the learning choice acts where its last 20 measured episodes are
  strictly above the clone's 20, each with 10 or more);
- `keep`: pre-registration 7 (a frozen candidate snapshot kept when the posterior probability that it
  is better than the kept policy is >= 0.9; dropped at <= 0.2 or after `max_candidate` episodes), and
  the variants its first run suggested.

    python studies/learner-from-demos/probe_gate_model.py      # about 10 s; prints the table

A probe, not a screen: its curves are models shaped like `igate100`'s, and it decides nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.special import betaln

Curve = Callable[[int, np.random.Generator], float]
RUNS = 200


def prob_better(a: list[bool], b: list[bool]) -> float:
    """P(p_a > p_b) with uniform priors on both success rates (an exact finite sum)."""
    a1, b1, a2, b2 = 1 + sum(a), 1 + len(a) - sum(a), 1 + sum(b), 1 + len(b) - sum(b)
    i = np.arange(a1)
    return float(np.exp(betaln(a2 + i, b1 + b2) - np.log(b1 + i) - betaln(1 + i, b1) - betaln(a2, b2)).sum())


def suction_rising(t: int, rng: np.random.Generator) -> float:
    """Clone 0.55; the learner rises from episode 50 (the warm-up) to 0.97 at episode 140."""
    base = 0.55 if t < 50 else min(0.97, 0.55 + (t - 50) * 0.42 / 90)
    return float(np.clip(base + rng.normal(0, 0.02), 0, 1))


def suction_declining(t: int, rng: np.random.Generator) -> float:
    """Rises faster to 0.97, then declines from episode 130, with dips of up to 0.10."""
    base = 0.55 if t < 50 else min(0.97, 0.55 + (t - 50) * 0.42 / 60)
    if t > 130:
        base = 0.97 - (t - 130) * 0.001
    return float(np.clip(base + rng.uniform(-0.1, 0.02), 0, 1))


def push(t: int, rng: np.random.Generator) -> float:
    """Clone 0.70; rises to 0.93 by episode 300, then each snapshot within +-0.04 of it."""
    base = 0.7 if t < 50 else min(0.93, 0.7 + (t - 50) * 0.23 / 250)
    return float(np.clip(base + (rng.uniform(-0.04, 0.04) if t > 300 else rng.normal(0, 0.02)), 0, 1))


def gripper(t: int, rng: np.random.Generator) -> float:
    """Clone 0.98; the learner's snapshots 0.85-0.99."""
    return 0.98 if t == 0 else float(rng.choice([0.99, 0.98, 0.97, 0.9, 0.85]))


#: name: (curve, training episodes, episodes between evaluations, env steps between them, target)
TASKS: dict[str, tuple[Curve, int, int, int, int]] = {
    "suction, rising": (suction_rising, 250, 25, 1_250, 12_500),
    "suction, declining": (suction_declining, 250, 25, 1_250, 12_500),
    "push": (push, 600, 50, 2_500, 30_000),
    "gripper": (gripper, 200, 25, 1_250, 5_000),
}


def igate(curve: Curve, episodes: int, every: int, rng: np.random.Generator) -> np.ndarray:
    clone = curve(0, rng)
    clone_measured: list[bool] = []
    window: list[bool] = []
    acts, live, evals = False, clone, []
    for t in range(episodes):
        live = curve(t, rng) if t > 0 else clone
        if t % every == 0:
            evals.append(rng.binomial(100, live if acts else clone) / 100)
        slot = t % 4
        if slot == 3 and len(clone_measured) < 20:
            clone_measured.append(bool(rng.random() < clone))
        elif slot == 1:
            window = [*window, bool(rng.random() < live)][-20:]
        acts = min(len(window), len(clone_measured)) >= 10 and np.mean(window) > np.mean(clone_measured)
    evals.append(rng.binomial(100, live if acts else clone) / 100)
    return np.array(evals)


def keep(
    curve: Curve, episodes: int, every: int, rng: np.random.Generator,
    max_candidate: int = 40, slot4_candidate: bool = False, min_to_keep: int = 10,
) -> np.ndarray:  # fmt: skip
    kept_p = curve(0, rng)
    kept: list[bool] = []
    kept_in_slot = 0
    candidate_p, candidate = 0.0, None
    evals = []
    for t in range(episodes):
        if t % every == 0:
            evals.append(rng.binomial(100, kept_p) / 100)
        kind = ("explore", "candidate", "explore", "kept")[t % 4]
        if kind == "kept" and kept_in_slot >= 20:
            kind = "candidate" if slot4_candidate else "explore"
        if kind == "candidate" and candidate is None:
            candidate_p, candidate = curve(t, rng), []
        if kind == "kept":
            kept.append(bool(rng.random() < kept_p))
            kept_in_slot += 1
        elif kind == "candidate":
            assert candidate is not None
            candidate.append(bool(rng.random() < candidate_p))
            measured = min(len(candidate), len(kept))
            if measured >= 5:
                better = prob_better(candidate, kept)
                if measured >= min_to_keep and better >= 0.9:
                    kept_p, kept, kept_in_slot, candidate = candidate_p, candidate, 0, None
                elif better <= 0.2 or len(candidate) >= max_candidate:
                    candidate = None
    evals.append(rng.binomial(100, kept_p) / 100)
    return np.array(evals)


def sustained(evals: np.ndarray, steps: int) -> int | None:
    """Env steps from which the mean of three consecutive evaluations stays >= 0.95 (None: never)."""
    means = np.convolve(evals, np.ones(3) / 3, "valid")
    return next((i * steps for i in range(len(means)) if (means[i:] >= 0.95).all()), None)


GATES: dict[str, tuple[Callable[..., np.ndarray], dict[str, Any]]] = {
    "igate (pre-registration 6)": (igate, {}),
    "keep (pre-registration 7)": (keep, {}),
    "keep, dropped after 20, measured twice as often": (keep, {"max_candidate": 20, "slot4_candidate": True}),
    "keep, as above, kept after 5": (keep, {"max_candidate": 20, "slot4_candidate": True, "min_to_keep": 5}),
}


def main() -> None:
    print("| model curve | gate | share of runs meeting the target | mean final (last 3) |")
    print("| --- | --- | ---: | ---: |")
    for task, (curve, episodes, every, steps, target) in TASKS.items():
        for name, (gate, options) in GATES.items():
            rng = np.random.default_rng(0)
            met, finals = 0, []
            for _ in range(RUNS):
                evals = gate(curve, episodes, every, rng, **options)
                crossing = sustained(evals, steps)
                met += crossing is not None and crossing <= target
                finals.append(evals[-3:].mean())
            print(f"| {task} | {name} | {met / RUNS:.2f} | {np.mean(finals):.3f} |")


if __name__ == "__main__":
    main()
