"""studies/manipulation-family/merge_saved.py: saved family runs of two measurements merged into one table (or compared
variant by variant), and its refusals (a run in two sources, sources of different tables, a source that
is not a measurement, a comparison of two tasks)."""

from __future__ import annotations

import itertools
import json
import shutil
from pathlib import Path

import pytest
from benchmark_modules import load_study

DATA = Path(__file__).resolve().parents[1] / "studies" / "manipulation-family" / "data"

from tsrl.experiments.milestones import RUN_FILES, saved_runs

merge_saved = load_study("manipulation-family", "merge_saved")
family_tables = load_study("manipulation-family", "family_tables")


def test_merged_runs_render_one_row_per_task_with_every_seed(tmp_path: Path) -> None:
    metas, runs = merge_saved.plan(["family-stack-peg", "family-peg-s2"])
    assert set(metas) == {"family-stack-peg", "family-peg-s2"}
    merge_saved.copy_runs(runs, tmp_path)
    rows = family_tables.table_family(tmp_path)[2:]
    peg = [r for r in rows if "PandaPegInsert" in r]
    assert len(peg) == 1 and "| 0, 1, 2 |" in peg[0]
    for rel, run_dir in runs.items():
        for name in RUN_FILES:
            assert (tmp_path / rel / name).read_bytes() == (run_dir / name).read_bytes()


def test_a_run_in_two_sources_is_refused() -> None:
    with pytest.raises(SystemExit, match="is in both 'family-stack-peg' and 'family-stack-peg'"):
        merge_saved.plan(["family-stack-peg", "family-stack-peg"])


def test_sources_of_different_tables_and_non_measurements_are_refused(tmp_path: Path) -> None:
    for name in ("family-stack-peg", "family-peg-s2"):
        shutil.copytree(DATA / name, tmp_path / name)
    meta_path = tmp_path / "family-peg-s2" / "meta.json"
    meta = json.loads(meta_path.read_text())
    meta_path.write_text(json.dumps(meta | {"table": "benchmarks/family_tables.py:table_demos"}))
    with pytest.raises(SystemExit, match="the sources' tables differ"):
        merge_saved.plan(["family-stack-peg", "family-peg-s2"], tmp_path)
    with pytest.raises(SystemExit, match="no saved measurement 'nothing-here'"):
        merge_saved.plan(["family-stack-peg", "nothing-here"], tmp_path)


def _auc_iqm(run_dirs: list[Path]) -> float:
    """IQM over runs of the normalised trapezoid area under each run's success curve, computed here
    with the standard library and scipy's trimmed mean (rliable's IQM), not the tables' code."""
    import csv

    from scipy.stats import trim_mean

    areas = []
    for run_dir in run_dirs:
        with open(run_dir / "progress.csv", newline="") as f:
            rows = [(float(r["env_steps"]), float(r["eval_success_rate"])) for r in csv.DictReader(f)]
        area = sum((x1 - x0) * (y0 + y1) / 2 for (x0, y0), (x1, y1) in itertools.pairwise(rows))
        areas.append(area / (rows[-1][0] - rows[0][0]))
    return float(trim_mean(areas, 0.25))


def test_comparison_puts_the_baseline_first_and_differences_its_auc_iqm(tmp_path: Path) -> None:
    _, runs = merge_saved.plan(["family-push-action-l2", "family-push-fast-intel"])
    merge_saved.copy_runs(runs, tmp_path)
    lines = family_tables.table_family_comparison(tmp_path)
    assert "minus learner fast, AUC IQM" in lines[0]
    baseline, penalty = (line.split(" | ") for line in lines[2:4])
    assert baseline[0] == "| learner fast" and baseline[1] == "2, 3" and baseline[5] == "-"
    assert penalty[0] == "| learner fast, action penalty 1" and penalty[1] == "0, 1, 2, 3, 4"
    groups: dict[str, list[Path]] = {"fast": [], "penalty": []}
    for run_dir in saved_runs(tmp_path):
        groups["penalty" if "action-l2" in run_dir.name else "fast"].append(run_dir)
    expected = _auc_iqm(groups["penalty"]) - _auc_iqm(groups["fast"])
    point, interval = penalty[5].split(" [")
    low, high = (float(x) for x in interval.rstrip("]").split(", "))
    assert float(point) == pytest.approx(expected, abs=5e-4) and low <= float(point) <= high
    assert penalty[6] == ("helps" if low > 0 else "hurts" if high < 0 else "not decided") + " |"


def test_comparison_of_two_tasks_is_refused(tmp_path: Path) -> None:
    _, runs = merge_saved.plan(["family-stack-peg"])
    merge_saved.copy_runs(runs, tmp_path)
    with pytest.raises(SystemExit, match="accepted: one task and one variant that adds least"):
        family_tables.table_family_comparison(tmp_path)


def test_a_task_files_runs_are_a_variant_of_the_family_task_its_solver_names(tmp_path: Path) -> None:
    _, runs = merge_saved.plan(["family-push-demos300", "family-push-half-step-demos300"])
    merge_saved.copy_runs(runs, tmp_path)
    lines = family_tables.table_family_comparison(tmp_path)
    assert lines[0].startswith("| `tsrl/PandaPush-v0` |")
    baseline, half_step = (line.split(" | ") for line in lines[2:4])
    assert baseline[0] == "| learner fast, 300 demonstrations" and baseline[5] == "-"
    assert half_step[0] == "| panda_push_half_step.toml, learner fast, 300 demonstrations"
    assert half_step[1] == "0, 1, 2, 3, 4" and half_step[6] != "-"
