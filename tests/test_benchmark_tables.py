"""Every benchmark table with committed data re-derives from it (scripts/benchmark_tables.py, issue 28):
the docs' copies equal what the data give, and a changed datum, a table without data or a marker that
names another data folder is reported."""

from __future__ import annotations

import importlib.util
import shutil
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _checker() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "benchmark_tables", ROOT / "scripts" / "benchmark_tables.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["benchmark_tables"] = module
    spec.loader.exec_module(module)
    return module


checker = _checker()


def test_every_docs_benchmark_table_is_what_its_committed_data_give() -> None:
    tables = checker.derived_tables()
    assert tables, "no benchmark table has committed data"
    assert checker.problems(tables) == []


def test_a_changed_datum_is_reported(tmp_path: Path) -> None:
    name = "taskmaps"
    for folder in checker.data_folders():  # every table's data, one changed
        shutil.copytree(folder, tmp_path / checker.data_path(folder))
    data = tmp_path / checker.data_path(checker.ROOT / "docs/results/benchmarks" / name) / "data.csv"
    lines = data.read_text().splitlines()
    head, first = lines[0].split(","), lines[2].split(",")  # the first preset after the physics row
    first[head.index("us")] = str(float(first[head.index("us")]) * 3.0)
    data.write_text("\n".join([lines[0], lines[1], ",".join(first), *lines[3:]]) + "\n")
    found = checker.problems(checker.derived_tables(checker.data_folders(tmp_path)))
    assert found == [f"docs/taskmaps.md: benchmark table {name!r} differs from what its data give"]


def test_a_marked_table_without_data_is_reported(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    begin = checker.BEGIN.format(name="nowhere", data="docs/results/benchmarks/nowhere")
    (tmp_path / "docs" / "x.md").write_text(f"{begin}\n| a |\n{checker.END.format(name='nowhere')}\n")
    (tmp_path / "README.md").write_text("")
    found = checker.problems({}, root=tmp_path)
    where = "docs/results/benchmarks/nowhere/ or studies/*/data/nowhere/"
    assert found == [f"docs/x.md: benchmark table 'nowhere' has no data ({where})"]


def test_missing_markers_are_one_line() -> None:
    with pytest.raises(SystemExit, match="markers of benchmark table 'x' are missing"):
        checker.with_table(
            "no markers", "x", checker.Table("docs/y.md", "docs/results/benchmarks/x", ["| a |"])
        )


def test_a_marker_naming_another_data_folder_is_reported() -> None:
    tables = checker.derived_tables([checker.ROOT / "docs" / "results" / "benchmarks" / "taskmaps"])
    table = tables["taskmaps"]
    text = (checker.ROOT / table.doc).read_text()
    moved = text.replace("from docs/results/benchmarks/taskmaps/", "from studies/x/data/taskmaps/")
    assert moved != text and checker.with_table(moved, "taskmaps", table) == text
