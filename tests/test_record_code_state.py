"""benchmarks/record.py: which files' uncommitted edits a saved measurement's meta.json names, and where its data go."""

from __future__ import annotations

import re

from benchmark_modules import load_benchmark

record = load_benchmark("record")


def test_the_table_renderers_module_counts_as_the_measurements_code() -> None:
    merge, tables = (
        "studies/manipulation-family/merge_saved.py",
        "studies/manipulation-family/family_tables.py",
    )
    assert record.code_files(merge, f"{tables}:table_family") == (merge, tables)
    assert record.code_files("benchmarks/solvers.py", "table") == ("benchmarks/solvers.py",)


def test_code_state_names_the_head_commit_and_only_files_it_was_asked_about() -> None:
    commit, dirty = record.code_state(("benchmarks/record.py",))
    assert re.fullmatch(r"[0-9a-f]{40}", commit)
    allowed = ("src", "pyproject.toml", "benchmarks/record.py", "benchmarks/fetch_compat.py")
    assert all(path.startswith(allowed) for path in dirty)


def test_a_studys_data_lie_beside_its_readme_and_a_docs_pages_under_docs_results() -> None:
    study = record.data_root("studies/manipulation-family/README.md")
    assert study == record.ROOT / "studies" / "manipulation-family" / "data"
    assert (
        record.data_root("docs/ik.md") == record.DATA_ROOT == record.ROOT / "docs" / "results" / "benchmarks"
    )
