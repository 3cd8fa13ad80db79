"""`tsrl experiment` and `tsrl report`: run an experiment's grid of runs; aggregate a results folder.

tsrl.cli calls add_experiment_commands(); each command's handler is `args.handler`. Bad input raises
TsrlError, which tsrl.cli turns into one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path
from typing import Any

#: Exit codes of `tsrl experiment` besides 0 (every run at its budget) and 2 (bad input).
EXIT_FAILED_RUNS = 1
EXIT_INTERRUPTED = 130


def add_experiment_commands(commands: Any) -> None:
    """Adds `experiment` and `report` to the `tsrl` subparsers `commands`."""
    p_exp = commands.add_parser(
        "experiment",
        help="run every run of an experiment definition (experiments/NAME.toml) and report it",
        description="Runs an experiment's grid (env x obs x action x algo x seeds) into <out-dir>/<name>/: "
        "finished runs are skipped, interrupted ones resume from their checkpoints, a failing one is "
        "reported (error.txt in its folder) while the others go on. Then writes the report (tsrl report).",
    )
    p_exp.add_argument(
        "experiment",
        metavar="NAME_OR_FILE",
        help="an experiment name (experiments/NAME.toml) or the path of a .toml definition",
    )
    p_exp.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="runs at a time (default: one per CPU core locally; the cluster's CPUs with --ray)",
    )
    p_exp.add_argument(
        "--ray",
        metavar="ADDRESS|local",
        default=None,
        help="run on the Ray cluster at ADDRESS (e.g. ray://head:10001 or auto), or on a new local Ray "
        "instance with 'local' (needs pip install 'tsrl[ray]'); default: local worker processes",
    )
    p_exp.add_argument(
        "--out-dir", type=Path, default=Path("results"), help="parent of the experiment folder"
    )
    p_exp.add_argument(
        "--report",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="write the report (results.csv, summary.csv, summary.md, learning curves) when done",
    )
    p_exp.set_defaults(handler=_cmd_experiment)

    p_report = commands.add_parser(
        "report",
        help="aggregate an experiment's runs: results.csv, summary.csv, summary.md, learning curves",
        description="Aggregates the run folders in RESULTS_DIR (e.g. results/quick-reach) into results.csv "
        "(one row per run and evaluation), summary.csv and summary.md (per configuration: IQM across seeds "
        "of the area under the success curve and of final success with 95% stratified-bootstrap intervals, "
        "Kaplan-Meier env steps to 50% and 90% success), comparisons.csv (the experiment's pre-registered "
        "comparisons: effect, interval, Holm-adjusted p, power, verdict), learning_curves.png and "
        "performance_profile.png.",
    )
    p_report.add_argument(
        "results_dir", type=Path, metavar="RESULTS_DIR", help="an experiment's results folder"
    )
    p_report.set_defaults(handler=_cmd_report)


def _cmd_experiment(args: argparse.Namespace) -> int:
    from ..exceptions import InvalidConfig
    from .config import load_experiment, resolve_experiment

    if args.workers is not None and args.workers < 1:
        raise InvalidConfig(f"--workers must be >= 1; got {args.workers}")
    if args.ray is not None and importlib.util.find_spec("ray") is None:
        raise InvalidConfig("--ray needs Ray: pip install 'tsrl[ray]'")
    exp = load_experiment(resolve_experiment(args.experiment))
    from .pool import run_experiment

    try:
        outcomes = run_experiment(exp, args.out_dir, workers=args.workers, ray_address=args.ray)
        interrupted = any(o.status == "interrupted" for o in outcomes)
    except KeyboardInterrupt:  # a second Ctrl-C
        interrupted = True
    if interrupted:
        print("tsrl experiment: interrupted; run it again to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    exp_dir = args.out_dir / exp.name
    if args.report and any(o.env_steps > 0 for o in outcomes):
        from .aggregate import write_report

        for path in write_report(exp_dir):
            print(f"wrote {path}")
    failed = [o for o in outcomes if o.status == "failed"]
    if failed:
        print(
            f"tsrl experiment: {len(failed)} run(s) failed; see error.txt in "
            + ", ".join(str(exp_dir / o.run_name) for o in failed),
            file=sys.stderr,
        )
        return EXIT_FAILED_RUNS
    return 0


def _cmd_report(args: argparse.Namespace) -> int:
    from .aggregate import write_report

    for path in write_report(args.results_dir):
        print(f"wrote {path}")
    return 0
