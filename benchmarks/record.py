"""A benchmark table's committed data (issue 28): `--save [NAME]` on a benchmark writes, under
docs/results/benchmarks/NAME/ (a study's: studies/<question>/data/NAME/), what its table is made of
(data.csv, or run folders) and meta.json (the command, the commit, the machine, the table's renderer
and the doc that shows it);
scripts/benchmark_tables.py re-derives every such table from them and checks (or writes) the doc's
copy between its markers.

A renderer is a function `table(data_dir: Path) -> list[str]` (markdown lines) in the benchmark's
module; modules keep their top-level imports light (stdlib, numpy) so that the check can import them.
"""

from __future__ import annotations

import argparse
import csv
import datetime as dt
import json
import os
import platform
import subprocess
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DATA_ROOT = ROOT / "docs" / "results" / "benchmarks"
META = "meta.json"
DATA_CSV = "data.csv"
#: Paths whose uncommitted edits make a measurement not the named commit's (and the benchmark itself).
CODE_PATHS = ("src", "pyproject.toml", "benchmarks/record.py", "benchmarks/fetch_compat.py")


def add_save_argument(parser: argparse.ArgumentParser, name: str) -> None:
    """`--save [NAME]`: commit-ready data of this run's table (docs/results/benchmarks/NAME/, or
    studies/<question>/data/NAME/ for a study's)."""
    parser.add_argument(
        "--save",
        nargs="?",
        const=name,
        default=None,
        metavar="NAME",
        help=f"write the table's data to docs/results/benchmarks/NAME/ or, a study's, to "
        f"studies/<question>/data/NAME/ (default NAME: {name})",
    )


def data_root(doc: str) -> Path:
    """Where the data of a table shown in `doc` (a repository path) live: beside a study's README
    (studies/<question>/data/), else docs/results/benchmarks/."""
    parts = Path(doc).parts
    return ROOT / "studies" / parts[1] / "data" if parts[0] == "studies" and len(parts) == 3 else DATA_ROOT


def data_dir(name: str, root: Path = DATA_ROOT) -> Path:
    """<root>/<name>/ (created)."""
    if not name or "/" in name or name.startswith("."):
        raise ValueError(f"benchmark data name {name!r}: a plain folder name")
    path = root / name
    path.mkdir(parents=True, exist_ok=True)
    return path


def write_rows(path: Path, rows: Iterable[dict[str, Any]]) -> Path:
    """`rows` (dicts with the same keys) as a CSV file; floats with repr's full precision."""
    rows = list(rows)
    if not rows:
        raise ValueError(f"{path}: no rows to write")
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file that `write_rows` wrote (values as strings)."""
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=False).stdout


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> dict[str, Any]:
    """The machine and its load now: CPU model, cores, load averages (1, 5, 15 min), versions."""
    import mujoco
    import numpy as np

    return {
        "cpu": _cpu(),
        "cores": os.cpu_count(),
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "python": platform.python_version(),
        "numpy": np.__version__,
        "mujoco": mujoco.__version__,
    }


def code_files(script: str, table: str) -> tuple[str, ...]:
    """The files besides CODE_PATHS whose edits change a measurement: the benchmark `script` and the
    module of its renderer `table` ("benchmarks/other.py:function", or a function of the script)."""
    module = table.split(":", 1)[0] if ":" in table else script
    return tuple(dict.fromkeys((script, module)))


def code_state(files: tuple[str, ...]) -> tuple[str, list[str]]:
    """(HEAD's commit, the files of CODE_PATHS and `files` with uncommitted edits)."""
    status = _git("status", "--porcelain", "--", *CODE_PATHS, *files)
    return _git("rev-parse", "HEAD").strip(), [line[3:] for line in status.splitlines() if line]


def save_meta(
    out: Path,
    script: str,
    table: str,
    doc: str,
    started: dt.datetime,
    load_at_start: list[float],
    code_at_start: tuple[str, list[str]],
) -> Path:
    """meta.json of a measurement: the command (this process's argv), the commit it started on and the
    files of CODE_PATHS, `script` and `table`'s module with uncommitted edits at its start or end (none: the measurement
    is the commit's; a commit made meanwhile is named as commit_at_end), the machine, the start and
    end (UTC), and where its table is rendered (`table`) and shown (`doc`)."""
    commit, dirty = code_at_start
    commit_at_end, dirty_at_end = code_state(code_files(script, table))
    meta = {
        "command": " ".join(["python", script, *sys.argv[1:]]),
        "commit": commit,
        "uncommitted_code": sorted(set(dirty) | set(dirty_at_end)),
        **({"commit_at_end": commit_at_end} if commit_at_end != commit else {}),
        "started_utc": started.isoformat(timespec="seconds"),
        "ended_utc": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "machine": machine() | {"load_average_at_start": load_at_start},
        "script": script,
        "table": table,
        "doc": doc,
    }
    path = out / META
    path.write_text(json.dumps(meta, indent=2) + "\n")
    return path


class Measurement:
    """Context of one saved measurement: `with Measurement(args.save, ...) as out:` yields the data
    folder (or None without --save) and writes meta.json when the block finishes without error."""

    def __init__(self, name: str | None, script: str, table: str, doc: str) -> None:
        """`script`: the benchmark's file (its `__file__`); `table`: its renderer, a function of the
        script or "benchmarks/other.py:function"; `doc`: the repository path of the doc that shows it."""
        self.name, self.table, self.doc = name, table, doc
        self.script = Path(script).resolve().relative_to(ROOT).as_posix()
        self.out: Path | None = None

    def __enter__(self) -> Path | None:
        self.started = dt.datetime.now(dt.UTC)
        self.load = [round(x, 2) for x in os.getloadavg()]
        self.code = code_state(code_files(self.script, self.table))
        if self.name is not None:
            self.out = data_dir(self.name, data_root(self.doc))
        return self.out

    def __exit__(self, exc_type: object, *_: object) -> None:
        if self.out is not None and exc_type is None:
            save_meta(self.out, self.script, self.table, self.doc, self.started, self.load, self.code)
            print(f"data: {self.out.relative_to(ROOT)}", flush=True)
