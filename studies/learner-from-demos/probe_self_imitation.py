"""Probe (README, "The stack's failures"): does BC climb when it also clones its own successes?

Iterated filtered BC, offline: round 0 is BC on the first N scripted demonstrations (pre-registration
1's BC); each next round records `--own` successful episodes with the last round's deterministic
policy (recording seed 100 + round, apart from the scripted seed 0 and the evaluation seeds) and
trains a fresh BC on the scripted demonstrations plus every round's own successes. Each round's
row (run.py's metrics: mean of the last three evaluations, 100 fresh seeds) goes to data/probes.csv
as arm `selfbcN-rK`.

    python studies/learner-from-demos/probe_self_imitation.py PandaStack-v0 --demos 100 --own 300 --rounds 3
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import run

from tsrl.agents.demo_files import ARRAYS, Demonstrations, load_demos, save_demos
from tsrl.agents.demonstrators import record_demos


def merged(scripted: Demonstrations, own: list[Demonstrations]) -> Demonstrations:
    """The scripted file's episodes followed by the own ones, under the scripted file's meta (same
    env, observation and action: recorded on the same task)."""
    arrays = {name: np.concatenate([getattr(d, name) for d in (scripted, *own)]) for name in ARRAYS}
    meta = dict(scripted.meta) | {"kept": int(arrays["seeds"].shape[0])}
    return Demonstrations(**arrays, meta=meta)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", choices=sorted(run.BUDGETS))
    parser.add_argument("--demos", type=int, default=100)
    parser.add_argument("--own", type=int, default=300, help="successful own episodes recorded per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results/learner-from-demos"))
    args = parser.parse_args()
    scripted_path = run.demo_file(args.out, args.task, args.demos)
    scripted = load_demos(scripted_path)
    own: list[Demonstrations] = []
    last_run: Path | None = None
    for k in range(args.rounds + 1):
        arm = f"selfbc{args.demos}-r{k}"
        if last_run is not None:
            recorded = record_demos(f"tsrl/{args.task}", args.own, policy=last_run, seed=100 + k)
            print(
                json.dumps(
                    {"round": k, "attempted": recorded.meta["attempted"], "kept": recorded.meta["kept"]}
                )
            )
            own.append(recorded)
        path = args.out / "demos" / f"{args.task}-{args.demos}-{arm}.npz"
        save_demos(merged(scripted, own), path)
        last_run = run.bc_probe(arm, args.task, args.seed, path, args.out)


if __name__ == "__main__":
    main()
