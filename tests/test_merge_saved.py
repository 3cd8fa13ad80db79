"""benchmarks/merge_saved.py: saved family runs of two measurements merged into one table, and its
refusals (a run in two sources, sources of different tables, a source that is not a measurement)."""

from __future__ import annotations

import importlib.util
import json
import shutil
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "docs" / "results" / "benchmarks"


def _module(name: str) -> ModuleType:
    sys.path.insert(0, str(ROOT / "benchmarks"))  # its siblings `record`, `learning_tables`
    spec = importlib.util.spec_from_file_location(name, ROOT / "benchmarks" / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


merge_saved = _module("merge_saved")
learning_tables = _module("learning_tables")


def test_merged_runs_render_one_row_per_task_with_every_seed(tmp_path: Path) -> None:
    metas, runs = merge_saved.plan(["family-stack-peg", "family-peg-s2"])
    assert set(metas) == {"family-stack-peg", "family-peg-s2"}
    merge_saved.copy_runs(runs, tmp_path)
    rows = learning_tables.table_family(tmp_path)[2:]
    peg = [r for r in rows if "PandaPegInsert" in r]
    assert len(peg) == 1 and "| 0, 1, 2 |" in peg[0]
    for rel, run_dir in runs.items():
        for name in learning_tables.RUN_FILES:
            assert (tmp_path / rel / name).read_bytes() == (run_dir / name).read_bytes()


def test_a_run_in_two_sources_is_refused() -> None:
    with pytest.raises(SystemExit, match="is in both 'family-stack-peg' and 'family-stack-peg'"):
        merge_saved.plan(["family-stack-peg", "family-stack-peg"])


def test_sources_of_different_tables_and_non_measurements_are_refused(tmp_path: Path) -> None:
    for name in ("family-stack-peg", "family-peg-s2"):
        shutil.copytree(DATA / name, tmp_path / name)
    meta_path = tmp_path / "family-peg-s2" / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta_path.write_text(json.dumps(meta | {"table": "benchmarks/learning_tables.py:table_demos"}))
    with pytest.raises(SystemExit, match="the sources' tables differ"):
        merge_saved.plan(["family-stack-peg", "family-peg-s2"], tmp_path)
    with pytest.raises(SystemExit, match="no saved measurement 'nothing-here'"):
        merge_saved.plan(["family-stack-peg", "nothing-here"], tmp_path)
