"""`tsrl experiment` and `tsrl report`: run an experiment's grid of runs; aggregate a results folder.

tsrl.cli adds EXPERIMENT_COMMANDS to its commands (tyro dataclasses: fields are options, run() the
work). Bad input raises TsrlError, which tsrl.cli turns into one line on stderr and exit code 2.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

from tyro.conf import Positional, arg

from ..exceptions import InvalidConfig

if TYPE_CHECKING:
    from .config import ExperimentConfig

#: Exit codes of `tsrl experiment` besides 0 (every run at its budget) and 2 (bad input).
EXIT_FAILED_RUNS = 1
EXIT_INTERRUPTED = 130


@dataclass(frozen=True)
class Experiment:
    """Run every run of an experiment definition (experiments/NAME.toml) and report it."""

    experiment: Positional[Annotated[str, arg(metavar="NAME_OR_FILE")]]
    """An experiment name (experiments/NAME.toml) or the path of a .toml definition. Its grid (env x obs
    x action x algo x seeds) runs into <out-dir>/<name>/: finished runs are skipped, interrupted ones
    resume from their checkpoints, a failing one is reported (error.txt in its folder) while the others
    go on; then the evaluation-only arms ([[evaluate]]) are evaluated on the finished runs, into
    evaluations.csv (kept across calls), and the report is written (tsrl report)."""
    workers: Annotated[int | None, arg(metavar="N")] = None
    """Runs at a time (default: one per CPU core locally; the cluster's CPUs with --ray), and runs
    evaluated at a time by the evaluation-only arms (local processes; one with --ray by default)."""
    ray: Annotated[str | None, arg(metavar="ADDRESS|local")] = None
    """Run on the Ray cluster at ADDRESS (e.g. ray://head:10001 or auto), or on a new local Ray instance
    with 'local' (needs pip install 'tsrl[ray]'); default: local worker processes."""
    out_dir: Path = Path("results")
    """Parent of the experiment folder."""
    report: bool = True
    """Write the report (results.csv, summary.csv, summary.md, learning curves) when done."""

    def __post_init__(self) -> None:
        if self.workers is not None and self.workers < 1:
            raise InvalidConfig(f"--workers must be >= 1; got {self.workers}")

    def run(self) -> int:
        return _cmd_experiment(self)


@dataclass(frozen=True)
class Report:
    """Aggregate an experiment's runs: results.csv, summary.csv, summary.md, learning curves."""

    results_dir: Positional[Annotated[Path, arg(metavar="RESULTS_DIR")]]
    """An experiment's results folder (e.g. results/quick-reach). Its run folders are aggregated into
    results.csv (one row per run and evaluation), summary.csv and summary.md (per configuration: IQM
    across seeds of the area under the success curve and of final success with 95% stratified-bootstrap
    intervals, Kaplan-Meier env steps to 50%, 90% and 95% success), comparisons.csv (the experiment's
    pre-registered comparisons: effect, interval, Holm-adjusted p, power, verdict), learning_curves.png
    and performance_profile.png."""

    def run(self) -> int:
        return _cmd_report(self)


#: The commands tsrl.cli adds to `tsrl`.
EXPERIMENT_COMMANDS: dict[str, type] = {"experiment": Experiment, "report": Report}


def _cmd_experiment(args: Experiment) -> int:
    from .config import load_experiment, resolve_experiment

    if args.ray is not None and importlib.util.find_spec("ray") is None:
        raise InvalidConfig("--ray needs Ray: pip install 'tsrl[ray]'")
    exp = load_experiment(resolve_experiment(args.experiment))
    from .pool import ExperimentStopped, stop_signals

    with stop_signals():  # a background job's SIGINT too; exit 128 + the signal's number
        try:
            return _experiment(args, exp)
        except ExperimentStopped as stop:
            print("tsrl experiment: interrupted; run it again to resume", file=sys.stderr)
            return 128 + stop.signum


def _experiment(args: Experiment, exp: ExperimentConfig) -> int:
    from .pool import run_experiment

    outcomes = run_experiment(exp, args.out_dir, workers=args.workers, ray_address=args.ray)
    if any(o.status == "interrupted" for o in outcomes):  # a run's own process was signalled
        print("tsrl experiment: interrupted; run it again to resume", file=sys.stderr)
        return EXIT_INTERRUPTED
    exp_dir = args.out_dir / exp.name
    if exp.evaluate:  # the evaluation-only arms, on the runs at their budget
        from .config import local_workers
        from .evaluations import run_evaluations

        workers = 1 if args.ray is not None and args.workers is None else local_workers(args.workers)
        run_evaluations(exp, exp_dir, sys.stderr, workers)
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


def _cmd_report(args: Report) -> int:
    from .aggregate import write_report

    for path in write_report(args.results_dir):
        print(f"wrote {path}")
    return 0
