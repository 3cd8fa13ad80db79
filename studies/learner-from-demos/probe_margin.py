"""A probe of the push's near misses (probe_failures.py): one `igate100` run whose reward counts a
step as a success only within `--radius` of the goal (2.5 cm) instead of the task's radius (5 cm).
Success as evaluation counts it (info["is_success"]) stays the task's; the demonstrations are recorded
under the same reward, in OUT's own cache.

    python studies/learner-from-demos/probe_margin.py TASK SEED --out DIR [--radius 0.025]

Run it beside run.py of the learner it probes (commit ef4c768 for igate100); the row goes to
data/probes.csv with arm igate100. A probe, not a screen: one seed, no verdict.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from run import train_arm  # type: ignore[import-not-found]

from tsrl.envs.goals import Goal


def reward_within(radius: float) -> None:
    """Goal.reward and Goal.outcome's reward: success within `radius` [m] (outcome's info unchanged)."""
    task_outcome = Goal.outcome

    def success(goal: Goal, squared: Any, dot: Any) -> Any:
        within = squared < radius**2
        return within if dot is None else within & (dot > goal._cos_half_tolerance)

    def reward(self: Goal, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        _, squared, dot, penalty, _ = self._evaluate(achieved, desired)
        return self._reward(success(self, squared, dot), penalty)

    def outcome(self: Goal, achieved: np.ndarray, desired: np.ndarray) -> tuple[float, dict[str, Any]]:
        _, info = task_outcome(self, achieved, desired)
        return float(self.reward(achieved, desired)), info

    Goal.reward = reward  # type: ignore[method-assign]
    Goal.outcome = outcome  # type: ignore[method-assign]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument("seed", type=int)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--radius", type=float, default=0.025)
    args = parser.parse_args()
    reward_within(args.radius)
    train_arm("igate100", args.task, [args.seed], args.out, probe=True)


if __name__ == "__main__":
    main()
