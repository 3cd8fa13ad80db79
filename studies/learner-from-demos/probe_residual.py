"""A probe of the stack's learner (README, "The stack's failures"): `margin100` with its actor a bounded
residual on the frozen clone (`--residual`, tsrl.agents.reference), so that the critic can correct the
clone's near misses but cannot take the actor far from it.

    python studies/learner-from-demos/probe_residual.py TASK SEED --out DIR [--residual 0.3]

The row goes to data/probes.csv (a run stopped before its budget writes none: its progress.csv is the
curve). A probe, not a screen: one seed, no verdict.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from run import BUDGETS, train_arm  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", choices=sorted(BUDGETS))
    parser.add_argument("seed", type=int)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--residual", type=float, default=0.3)
    args = parser.parse_args()
    train_arm(
        "margin100", args.task, [args.seed], args.out, probe=True,
        change=lambda agent: dataclasses.replace(agent, residual=args.residual),
    )  # fmt: skip


if __name__ == "__main__":
    main()
