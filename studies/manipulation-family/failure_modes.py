"""The failure classes (tsrl.experiments.failures) of trained runs of the manipulation family, each
labelled with what sets it apart (family_tables.family_variant), as a saved measurement.

    python studies/manipulation-family/failure_modes.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--save [NAME]]

--save writes the rows to docs/results/benchmarks/NAME/ (default failure-modes) with meta.json
(benchmarks/record.py); tsrl.experiments.failures.table renders their table.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # record: saved measurements

from family_tables import family_variant
from record import DATA_CSV, Measurement, add_save_argument, write_rows

from tsrl.experiments.failures import failure_modes, render


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN_DIR")
    parser.add_argument("--episodes", type=int, default=100)
    add_save_argument(parser, "failure-modes")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1; got {args.episodes}")
    table = "src/tsrl/experiments/failures.py:table"
    with Measurement(args.save, __file__, table, "studies/manipulation-family/README.md") as out:
        rows = [row for run in args.runs for row in failure_modes(run, args.episodes, family_variant)]
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))


if __name__ == "__main__":
    main()
