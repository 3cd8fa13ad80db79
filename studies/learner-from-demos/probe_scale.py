"""A probe of the suction's late declines (pre-registration 9's result): one `margin100-press` run with
the reward at the task's own radius (reward scale 1, pre-registration 6's reward) instead of the fast
preset's half, on the same demonstrations.

    python studies/learner-from-demos/probe_scale.py SEED --out DIR [--reward-scale 1.0]

The row goes to data/probes.csv. A probe, not a screen: one seed, no verdict.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from run import train_arm  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("seed", type=int)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--reward-scale", type=float, default=1.0)
    args = parser.parse_args()
    train_arm(
        "margin100-press", "UR5ePickPlace-v0", [args.seed], args.out, probe=True,
        change=lambda agent: dataclasses.replace(agent, reward_scale=args.reward_scale),
    )  # fmt: skip


if __name__ == "__main__":
    main()
