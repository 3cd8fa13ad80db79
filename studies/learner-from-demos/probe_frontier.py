"""A probe of the stack's plateau (the stack probe above): one `margin100` run on PandaStack-v0 with
RFCL's reverse curriculum on (`--demos-reset-frontier-k K`, episodes started from demonstration
states near each demonstration's frontier with probability `--reset-prob`).

    python studies/learner-from-demos/probe_frontier.py SEED --out DIR [--k 3] [--reset-prob 0.5]

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
    parser.add_argument("--k", type=int, default=3)
    parser.add_argument("--reset-prob", type=float, default=0.5)
    args = parser.parse_args()
    curriculum = {"reset_prob": args.reset_prob, "reset_frontier_k": args.k}
    train_arm(
        "margin100", "PandaStack-v0", [args.seed], args.out, probe=True,
        change=lambda agent: dataclasses.replace(agent, demos=dataclasses.replace(agent.demos, **curriculum)),
    )  # fmt: skip


if __name__ == "__main__":
    main()
