"""Runs trained by `tsrl experiment` saved as a measurement for a study's committed table: each run
folder's progress.csv and config.json and the experiment's experiment.json copied to
studies/<question>/data/NAME/<experiment>/, and meta.json (benchmarks/record.py) naming the table's
renderer, a function of a module in the study's folder. Nothing is trained here; meta.json's commit is
the one the runs are saved at, so save at the commit they ran at. `make reproduce-check` re-derives the
table into the study's README between its markers (scripts/benchmark_tables.py).

    tsrl experiment manipulation-family --workers 2
    python scripts/save_experiment.py results/manipulation-family \
        --table studies/manipulation-family/family_tables.py:table_family --save family-NAME
    python scripts/save_experiment.py results/learner-her \
        --table studies/learner-benchmarks/learner_tables.py:table_wall --save learning-NAME
"""

from __future__ import annotations

import argparse
import re
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))  # record: saved measurements

from record import Measurement, data_root

from tsrl.experiments.config import EXPERIMENT_FILE
from tsrl.experiments.milestones import save_runs
from tsrl.experiments.results import find_runs

#: A study's table renderer: studies/<question>/<module>.py:<function>.
TABLE = re.compile(r"studies/(?P<question>[^/]+)/[A-Za-z_][A-Za-z0-9_]*\.py:[A-Za-z_][A-Za-z0-9_]*")


def copy_experiment(results_dir: Path, out: Path) -> int:
    """Copies the runs of the experiment folder `results_dir` that have evaluations (their
    progress.csv and config.json) and its experiment.json to out/<its name>/; returns how many runs.
    Raises InvalidConfig naming the folder where it holds no run folders."""
    runs = [run for run in find_runs(results_dir) if (run / "progress.csv").is_file()]
    save_runs(runs, out)
    if (results_dir / EXPERIMENT_FILE).is_file():
        shutil.copyfile(results_dir / EXPERIMENT_FILE, out / results_dir.name / EXPERIMENT_FILE)
    return len(runs)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("results", type=Path, nargs="+", metavar="RESULTS_DIR", help="experiment folders")
    parser.add_argument(
        "--table", required=True, metavar="PATH:FUNCTION", help="studies/<question>/<module>.py:<function>"
    )
    parser.add_argument("--save", required=True, metavar="NAME", help="the data's new folder name")
    args = parser.parse_args(argv)
    table = TABLE.fullmatch(args.table)
    if table is None or not Path(args.table.split(":")[0]).is_file():
        parser.error(f"--table {args.table}: accepted: studies/<question>/<module>.py:<function>, a file")
    doc = f"studies/{table['question']}/README.md"
    if (data_root(doc) / args.save).exists():
        parser.error(f"--save {args.save}: {data_root(doc) / args.save} exists; accepted: a new name")
    names = [results.name for results in args.results]
    if len(set(names)) < len(names):
        parser.error(f"experiment folders of one name: {names}; accepted: distinct experiments")
    with Measurement(args.save, __file__, args.table, doc) as out:
        assert out is not None
        count = sum(copy_experiment(results, out) for results in args.results)
    print(f"{count} runs saved")


if __name__ == "__main__":
    main()
