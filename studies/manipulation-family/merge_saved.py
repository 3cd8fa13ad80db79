"""One table from several saved measurements of the same benchmark: the run folders of each
data/SOURCE/ beside this file (measurements that save run folders, the family's, trained in parts:
seeds 0-1 in one session, seed 2 in the next) copied into one new data folder whose table is rendered
by the sources' renderer, so that a task's seeds stand in one row. Nothing is re-trained; meta.json
names every source (its command, commit and training times).

    python studies/manipulation-family/merge_saved.py family-stack-peg family-peg-s2 --save family-stack-peg-5-seeds
    python studies/manipulation-family/merge_saved.py family-push-action-l2 family-push-fast-intel \
        --table table_family_comparison --save family-push-penalty-vs-fast   # variants side by side
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # record: saved measurements

from record import META, Measurement, data_root

from tsrl.experiments.milestones import RUN_FILES, saved_runs

#: The family's README, and where its tables' data are (data/ beside it).
DOC = "studies/manipulation-family/README.md"
DATA_ROOT = data_root(DOC)
#: Renderers of family_tables.py (beside this file) that `--table` may give merged run folders.
TABLES_MODULE = "studies/manipulation-family/family_tables.py"
MERGED_TABLES = ("table_family", "table_family_comparison")
#: The meta.json keys of a source kept in the merged meta.json's "sources".
SOURCE_KEYS = ("command", "commit", "started_utc", "ended_utc", "trained")


def plan(names: list[str], data_root: Path = DATA_ROOT) -> tuple[dict[str, Any], dict[Path, Path]]:
    """(each source's meta.json by name, {<group>/<run name>: the source's run folder}) of the saved
    measurements `names` under `data_root`; raises SystemExit naming the source and the accepted input
    when one has no meta.json or no run folders, their tables differ, or two hold the same run (a merge
    never chooses between two measurements)."""
    metas: dict[str, Any] = {}
    runs: dict[Path, Path] = {}
    owner: dict[Path, str] = {}
    for name in names:
        meta_path = data_root / name / META
        if not meta_path.is_file():
            raise SystemExit(f"{meta_path}: no saved measurement {name!r}; accepted: a folder of {data_root}")
        metas[name] = json.loads(meta_path.read_text())
        found = saved_runs(meta_path.parent)
        if not found:
            raise SystemExit(f"{meta_path.parent}: no run folders (<group>/<run>/progress.csv) to merge")
        for run_dir in found:
            rel = run_dir.relative_to(meta_path.parent)
            if rel in owner:
                raise SystemExit(
                    f"run {rel} is in both {owner[rel]!r} and {name!r}; accepted: sources of distinct runs"
                )
            owner[rel], runs[rel] = name, run_dir
    tables = {name: (meta["table"], meta["doc"]) for name, meta in metas.items()}
    if len(set(tables.values())) > 1:
        raise SystemExit(f"the sources' tables differ: {tables}; accepted: sources of one benchmark's table")
    return metas, runs


def copy_runs(runs: dict[Path, Path], out: Path) -> None:
    """Copies the RUN_FILES of each run folder to out/<group>/<run name>/."""
    for rel, run_dir in runs.items():
        (out / rel).mkdir(parents=True, exist_ok=True)
        for file in RUN_FILES:
            shutil.copyfile(run_dir / file, out / rel / file)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "sources", nargs="+", help="names of saved measurements (data/NAME/ beside this file)"
    )
    parser.add_argument("--save", required=True, metavar="NAME", help="the merged data's new folder name")
    parser.add_argument(
        "--table",
        choices=sorted(MERGED_TABLES),
        help="render the merged runs with this table of family_tables.py instead of the "
        "sources' own (e.g. table_family_comparison: variants of one task against its baseline)",
    )
    args = parser.parse_args(argv)
    if (DATA_ROOT / args.save).exists():
        parser.error(f"--save {args.save}: {DATA_ROOT / args.save} exists; accepted: a new name")
    metas, runs = plan(args.sources)
    table = next(m["table"] for m in metas.values())
    if args.table:
        table = f"{TABLES_MODULE}:{args.table}"
    with Measurement(args.save, __file__, table, DOC) as out:
        assert out is not None
        copy_runs(runs, out)
    meta_path = out / META
    meta = json.loads(meta_path.read_text())
    meta["sources"] = {
        name: {key: src[key] for key in SOURCE_KEYS if key in src} for name, src in metas.items()
    }
    meta_path.write_text(json.dumps(meta, indent=2) + "\n")
    print(f"{len(runs)} runs from {len(metas)} sources")


if __name__ == "__main__":
    main()
