"""Runs of the manipulation family trained by `tsrl experiment` (experiments/manipulation-family.toml
or a variant of it) saved as a measurement for a committed table: each run folder's RUN_FILES and the
experiment's experiment.json copied to data/NAME/<experiment>/ beside this file, and meta.json
naming the family's table (family_tables.py beside this file). Nothing is trained here; meta.json's
commit is the one the runs are saved at, so save at the commit they ran at.

    tsrl experiment manipulation-family --workers 2
    python studies/manipulation-family/save_experiment.py results/manipulation-family --save family-NAME
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # record: saved measurements

from record import Measurement, data_root

from tsrl.experiments.config import EXPERIMENT_FILE
from tsrl.experiments.milestones import save_runs
from tsrl.experiments.results import find_runs

#: The family's renderers (family_tables.py) that `--table` may name.
TABLES = ("table_family", "table_family_comparison")
TABLES_MODULE = "studies/manipulation-family/family_tables.py"
DOC = "studies/manipulation-family/README.md"


def copy_experiment(results_dir: Path, out: Path) -> int:
    """Copies the runs of the experiment folder `results_dir` that have evaluations (RUN_FILES) and
    its experiment.json to out/<its name>/; returns how many runs. Raises InvalidConfig naming the
    folder where it holds no run folders."""
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
    parser.add_argument("--save", required=True, metavar="NAME", help="the data's new folder name")
    parser.add_argument(
        "--table",
        choices=TABLES,
        default=TABLES[0],
        help="the table of family_tables.py (default table_family; table_family_comparison: variants "
        "of one task against its baseline)",
    )
    args = parser.parse_args(argv)
    if (data_root(DOC) / args.save).exists():
        parser.error(f"--save {args.save}: {data_root(DOC) / args.save} exists; accepted: a new name")
    names = [results.name for results in args.results]
    if len(set(names)) < len(names):
        parser.error(f"experiment folders of one name: {names}; accepted: distinct experiments")
    table = f"{TABLES_MODULE}:{args.table}"
    with Measurement(args.save, __file__, table, DOC) as out:
        assert out is not None
        count = sum(copy_experiment(results, out) for results in args.results)
    print(f"{count} runs saved")


if __name__ == "__main__":
    main()
