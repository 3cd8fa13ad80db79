"""Pre-registration 38: the training time of an arm's runs to their sustained 95 %, measured as the
issue's suction target reads it (README.md beside this file).

    python studies/learner-from-demos/time_to_target.py ARM TASK --seed S --out DIR

Trains the arm's run for seed S from scratch under DIR (run.py's configuration and demonstrations)
and prints one row: the env steps from which 95 % holds (tsrl.experiments.curves.sustained_crossing),
the setup time (environment, demonstrations and behaviour cloning before the first env step; the
process's monotonic clock less the run's own wall time), and the training time to the crossing: setup
plus the run's wall time at that evaluation less the evaluations' time up to it [s]. Run it on an idle
core: the time is the point.
"""

from __future__ import annotations

import math
import time

from run import arm_config, demo_count, demo_file, one_run_parser

from tsrl.agents import train
from tsrl.agents.training import read_progress
from tsrl.experiments.curves import sustained_crossing


def main() -> None:
    parser = one_run_parser(__doc__.splitlines()[0])
    args = parser.parse_args()
    demos = demo_file(args.out, args.task, demo_count(args.arm))  # recorded before the clock starts
    cfg = arm_config(args.arm, args.task, args.seed, demos)
    start = time.monotonic()
    run_dir = train(cfg, args.out / args.arm / args.task, progress_bar=False)
    total = time.monotonic() - start
    rows = read_progress(run_dir)
    setup = total - rows[-1]["wall_time_s"]
    clock = [r["env_steps"] for r in rows]
    success = [r["eval_success_rate"] for r in rows]
    crossing = sustained_crossing(clock, success, 0.95)
    if math.isnan(crossing):
        at = "-"
    else:
        row = rows[clock.index(crossing)]
        at = f"{setup + row['wall_time_s'] - row['eval_time_s']:.1f}"
    print(
        f"| {args.arm} | {args.task} | {args.seed} | {'-' if math.isnan(crossing) else f'{crossing:,.0f}'} | "
        f"{setup:.1f} | {at} | {total:.1f} | {' '.join(f'{s:.2f}' for s in success)} |",
        flush=True,
    )


if __name__ == "__main__":
    main()
