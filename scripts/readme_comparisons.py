"""Every pre-registered comparison of every committed study (studies/<question>/<screen>/ with
experiment.json and results.csv), recomputed from the committed data, Holm-corrected over all of them beside each study's
own correction (tsrl.experiments.across): prints the table and writes it to docs/results/comparisons-all.csv
and .md (the docs site's page of it); --check writes nothing and exits 1 when either committed file is not
what the data give, or a study README's result line quotes a number its data do not give
(scripts/study_numbers.py; make reproduce-check).

    python scripts/readme_comparisons.py [--check]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import study_numbers
from study_folders import screen_folders

from tsrl.experiments.across import (
    CSV_COLUMNS,
    correct_across,
    markdown_table,
    study_comparisons,
    study_folders,
)
from tsrl.experiments.aggregate import write_csv

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
PAGE, CSV = RESULTS / "comparisons-all.md", RESULTS / "comparisons-all.csv"


def page(rows: list[dict], table: list[str]) -> str:
    """docs/results/comparisons-all.md: the table with what its columns are."""
    return (
        "# Every pre-registered comparison, corrected across studies\n\n"
        "Every pre-registered comparison of every study on [the results page](../results.md), recomputed "
        "from each study's committed results.csv and experiment.json by `python "
        "scripts/readme_comparisons.py` (`make reproduce-check` fails when this page is not what the data "
        f"give): p with its method, Holm within the study and across all {len(rows)}, both verdicts, "
        "floor/ceiling flags, and the comparisons that reuse an arm's runs "
        '([columns](../statistics.md#across-studies)). The column "same runs as" marks runs '
        "shared within a study; a study re-run with the same seeds (her-strength's `final` row against "
        "paper-observations-v2) is the same runs too, bit for bit, and is not marked.\n\n"
        + "\n".join(table)
        + "\n"
    )


def studies() -> list[Path]:
    """Every committed screen whose experiment.json registers comparisons, sorted by name."""
    screens = {p.parent for p in screen_folders()}
    return sorted((f for q in screens for f in study_folders(q)), key=lambda p: p.name)


def write_files(rows: list[dict], table: list[str], md: Path = PAGE, csv: Path = CSV) -> None:
    """The table's page and CSV."""
    write_csv(csv, [{k: r[k] for k in CSV_COLUMNS} for r in rows], CSV_COLUMNS)
    md.write_text(page(rows, table))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--check", action="store_true", help="compare with the committed files, write nothing"
    )
    args = parser.parse_args(argv)
    rows = correct_across([r for folder in studies() for r in study_comparisons(folder)])
    table = markdown_table(rows)
    if args.check:
        with tempfile.TemporaryDirectory() as tmp:
            md, csv = Path(tmp) / PAGE.name, Path(tmp) / CSV.name
            write_files(rows, table, md, csv)
            differ = [p for p, q in ((PAGE, md), (CSV, csv)) if p.read_text() != q.read_text()]
        for path in differ:
            print(
                f"{path.relative_to(ROOT)}: the across-study comparisons differ from the committed data",
                file=sys.stderr,
            )
        quoted = study_numbers.check(rows)
        for line in quoted:
            print(line, file=sys.stderr)
        if differ or quoted:
            return 1
        print(f"{PAGE.relative_to(ROOT)}: {len(rows)} comparisons as the committed data give them")
        print("studies/*/README.md: every number quoted in a result line is what the data give")
        return 0
    write_files(rows, table)
    print("\n".join(table))
    return 0


if __name__ == "__main__":
    sys.exit(main())
