"""A probe of the stack's plateau (the stack probe above): one `margin100` run on PandaStack-v0 with
RFCL's reverse curriculum on (`--demos-reset-frontier-k K`, episodes started from demonstration
states near each demonstration's frontier with probability `--reset-prob`).

    python studies/learner-from-demos/probe_frontier.py SEED --out DIR [--k 3] [--reset-prob 0.5]
    python studies/learner-from-demos/probe_frontier.py --frontiers RUN_DIR

The row goes to data/probes.csv. A probe, not a screen: one seed, no verdict. `--frontiers` prints,
for the newest checkpoint of a run with the curriculum, each demonstration's frontier (the state
index episodes start near) beside its first successful state, and how many moved.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from run import train_arm  # type: ignore[import-not-found]

from tsrl.agents.checkpoint import DEMO_RESETS, verify_checkpoint
from tsrl.agents.demo_files import load_demos
from tsrl.agents.demo_resets import first_successes
from tsrl.agents.run_folder import checkpoint_dirs, load_config


def print_frontiers(run_dir: Path) -> None:
    """The newest checkpoint's frontiers of `run_dir` against the demonstrations' first successes."""
    cfg = load_config(run_dir)
    checkpoint = verify_checkpoint(checkpoint_dirs(run_dir)[-1], cfg.agent.normalize, for_training=True)
    state = checkpoint.rng[DEMO_RESETS]
    first = [int(f) for f in first_successes(load_demos(cfg.agent.demos.path))]
    frontier = state["frontier"]
    moved = [f < s for f, s in zip(frontier, first, strict=True)]
    print(
        f"{checkpoint.path.name}: {sum(moved)} of {len(frontier)} frontiers moved back; at the start: "
        f"{sum(f == 0 for f in frontier)}"
    )
    print("| demonstration | first success (state) | frontier (state) |")
    print("| ---: | ---: | ---: |")
    for i, (s, f) in enumerate(zip(first, frontier, strict=True)):
        print(f"| {i} | {s} | {f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("seed", type=int, nargs="?")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--k", type=int, default=3)
    parser.add_argument("--reset-prob", type=float, default=0.5)
    parser.add_argument("--frontiers", type=Path, metavar="RUN_DIR")
    args = parser.parse_args()
    if args.frontiers is not None:
        print_frontiers(args.frontiers)
        return
    if args.seed is None or args.out is None:
        parser.error("a probe run needs SEED and --out")
    curriculum = {"reset_prob": args.reset_prob, "reset_frontier_k": args.k}
    train_arm(
        "margin100", "PandaStack-v0", [args.seed], args.out, probe=True,
        change=lambda agent: dataclasses.replace(agent, demos=dataclasses.replace(agent.demos, **curriculum)),
    )  # fmt: skip


if __name__ == "__main__":
    main()
