"""The comparisons across studies (tsrl.experiments.across): Holm over every study's comparisons,
hand-computed on two small studies written as committed folders (results.csv and experiment.json);
shared runs and flags; and a committed study's comparison re-derived from its committed data."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from tsrl.experiments import across
from tsrl.experiments.aggregate import RESULT_COLUMNS

STUDIES = Path(__file__).resolve().parents[2] / "studies"


def _study(root: Path, name: str, arms: dict[str, list[float]], comparisons: list[dict]) -> None:
    """A committed study: each seed's success is its value at both evaluations (0 and 100 env steps),
    so its AUC and final success are that value."""
    folder = root / name
    folder.mkdir()
    with open(folder / "results.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=RESULT_COLUMNS)
        writer.writeheader()
        for obs, values in arms.items():
            for seed, v in enumerate(values):
                for steps in (0, 100):
                    writer.writerow(
                        {"env": "tsrl/UR5eReach-v0", "obs": obs, "action": "taskspace", "algo": "ddpg",
                         "variant": "", "seed": seed, "eval_episodes": 50, "env_steps": steps,
                         "episodes": steps // 50, "wall_time_s": 1.0, "eval_success_rate": v,
                         "eval_penalised_rate": ""}
                    )  # fmt: skip
    (folder / "experiment.json").write_text(json.dumps({"name": name, "comparisons": comparisons}))


def _greater(a: str, b: str) -> dict:
    return {"a": a, "b": b, "metric": "auc", "direction": "greater", "min_effect": 0.05}


def test_holm_across_studies_beside_each_studys_own(tmp_path):
    control = [0.1, 0.2, 0.3]
    # s1: x above every control seed: exact one-sided p = 1 / C(6, 3) = 0.05.
    _study(tmp_path, "s1", {"x": [0.7, 0.8, 0.9], "c": control}, [_greater("x", "c")])
    # s2, the same control runs: a above all of them (p = 0.05); b = (0.25, 0.35, 0.95) beats 8 of the 9
    # pairs, U = 8, P(U >= 8) = 2 / 20 = 0.1.
    _study(
        tmp_path, "s2", {"a": [0.6, 0.75, 0.99], "b": [0.25, 0.35, 0.95], "c": control},
        [_greater("a", "c"), _greater("b", "c")],
    )  # fmt: skip
    (tmp_path / "notes").mkdir()  # a folder without a study is not one
    rows = across.across(tmp_path)
    assert [(r["study"], r["a"]) for r in rows] == [("s1", "x"), ("s2", "a"), ("s2", "b")]
    assert [r["p"] for r in rows] == pytest.approx([0.05, 0.05, 0.1])
    assert {r["p_method"] for r in rows} == {"exact"}
    # Each study's own Holm: s1 alone 0.05; s2: 2 x 0.05 = 0.1, then max(0.1, 1 x 0.1) = 0.1.
    assert [r["p_holm"] for r in rows] == pytest.approx([0.05, 0.1, 0.1])
    # Across all three: sorted 0.05, 0.05, 0.1 -> 3 x 0.05 = 0.15, max(0.15, 2 x 0.05), max(0.15, 0.1).
    assert [r["p_holm_all"] for r in rows] == pytest.approx([0.15, 0.15, 0.15])
    assert all(r["verdict_all"].startswith("no detectable difference") for r in rows)
    # The control's runs are the same in all three comparisons.
    assert rows[0]["shared"] == "c with s2"
    assert rows[1]["shared"] == "c with b > c (auc); c with s1"
    # a's AUC interval reaches 0.99: at the ceiling.
    assert rows[1]["flags"] == "a: ceiling" and rows[0]["flags"] == ""
    table = across.markdown_table(rows)
    assert len(table) == 2 + 3 and "p Holm, all 3" in table[0]
    assert "| s2 | a > c (auc) | " in table[3] and "| 0.05 (exact) | 0.1 |" in table[3]


def test_a_committed_study_is_re_derived_from_its_data():
    """pick-place-suction's one comparison, recomputed from its committed results.csv, is its committed
    comparisons.csv row (effect, intervals, exact p: no two seeds' AUC tie)."""
    folder = STUDIES / "pick-place-features" / "pick-place-suction"
    with open(folder / "comparisons.csv", newline="") as f:
        committed = next(csv.DictReader(f))
    (row,) = across.study_comparisons(folder)
    for key in ("effect", "effect_ci_low", "effect_ci_high", "poi", "p", "p_holm", "mde"):
        assert row[key] == pytest.approx(float(committed[key]), rel=1e-5)
    assert row["p_method"] == committed["p_method"] == "exact"
    assert row["verdict"] == committed["verdict"]
