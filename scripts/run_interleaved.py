"""Runs several experiments' runs one at a time, interleaved seed-major across the experiments (seed 0 of
every experiment's every configuration, then seed 1, ...), so that a study made of several experiment
files (e.g. a 2 x 2 whose rows differ in [agent] settings, which are no grid axis) has the same seeds in
every cell whenever it stops. Each run goes into `<out-dir>/<experiment>/` exactly as `tsrl experiment`
puts it (experiment.json, run folders; finished runs are skipped, interrupted ones resume), so
`tsrl report` and a later `tsrl experiment` read and continue them.

    python scripts/run_interleaved.py her-strength-final her-strength-future --deadline 19:10

--deadline HH:MM (today, local time): no run starts that would, at the mean duration of the runs this
call has finished (or --first-estimate seconds before any has), end after it.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import sys
import time
from pathlib import Path

from tsrl.experiments.config import EXPERIMENT_FILE, load_experiment, resolve_experiment
from tsrl.experiments.runner import run_one, run_state
from tsrl.files import write_atomic


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("experiments", nargs="+", help="experiment names or .toml files")
    parser.add_argument("--out-dir", type=Path, default=Path("results"))
    parser.add_argument("--deadline", help="HH:MM today: start no run that would end after it")
    parser.add_argument(
        "--first-estimate", type=float, default=120.0, help="seconds per run before one finished"
    )
    args = parser.parse_args(argv)
    deadline = None
    if args.deadline:
        hour, minute = (int(x) for x in args.deadline.split(":"))
        deadline = dt.datetime.now().replace(hour=hour, minute=minute, second=0, microsecond=0).timestamp()
    exps = [load_experiment(resolve_experiment(name)) for name in args.experiments]
    seeds = exps[0].seeds
    if any(e.seeds != seeds for e in exps):
        sys.exit("run_interleaved: the experiments must list the same seeds")
    queue = []
    for exp in exps:
        exp_dir = args.out_dir / exp.name
        exp_dir.mkdir(parents=True, exist_ok=True)
        write_atomic(exp_dir / EXPERIMENT_FILE, json.dumps(exp.to_dict(), indent=2) + "\n")
        per_seed = len(exp.runs()) // len(seeds)
        for i, cfg in enumerate(exp.runs(exp_dir.resolve())):
            queue.append((i // per_seed, exps.index(exp), i, cfg, exp_dir))
    queue.sort(key=lambda q: q[:3])  # seed-major across the experiments
    durations: list[float] = []
    for _, _, _, cfg, exp_dir in queue:
        if run_state(cfg, exp_dir / cfg.run_name) != "finished" and deadline is not None:
            expected = sum(durations) / len(durations) if durations else args.first_estimate
            if time.time() + expected > deadline:
                print(f"deadline: not starting {exp_dir.name}/{cfg.run_name} (~{expected:.0f} s)", flush=True)
                continue
        outcome = run_one(cfg, exp_dir)
        if outcome.status in ("trained", "resumed"):
            durations.append(outcome.seconds)
        print(
            f"{time.strftime('%H:%M:%S')} {exp_dir.name}/{outcome.run_name}: {outcome.status}, "
            f"{outcome.env_steps} env steps, success {outcome.success:.2f}, {outcome.seconds:.0f} s"
            + (f" ({outcome.error})" if outcome.error else ""),
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
