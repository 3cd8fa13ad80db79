"""A probe of the suction's grasp (probe_suction.py): one run of ARM on demonstrations recorded by a
scripted pick-and-place whose descent targets `--depth` below the box top (PickPlaceSolver.GRIP_DEPTH:
0.004 m when this probe ran at 4b7de07, 0.015 m since pre-registration 9), in OUT's own demonstration
cache.

    python studies/learner-from-demos/probe_press.py ARM SEED --out DIR [--depth 0.015]

The row goes to data/probes.csv. A probe, not a screen: one seed, no verdict.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from run import train_arm  # type: ignore[import-not-found]

from tsrl.envs.solvers import PickPlaceSolver


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("arm")
    parser.add_argument("seed", type=int)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--depth", type=float, default=0.015)
    args = parser.parse_args()
    PickPlaceSolver.GRIP_DEPTH = args.depth
    train_arm(args.arm, "UR5ePickPlace-v0", [args.seed], args.out, probe=True)


if __name__ == "__main__":
    main()
