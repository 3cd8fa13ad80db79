"""Comparisons across studies: every pre-registered comparison of every committed study folder
(studies/<question>/<screen>/ with experiment.json and results.csv), recomputed from the committed
data, with Holm's correction over all of them beside each study's own, and the arms whose runs two
comparisons share (a shared control arm makes two comparisons one design, not two replications).

scripts/readme_comparisons.py prints the table and writes it to docs/results/comparisons-all.csv and
.md; tests check it against hand-computed values.
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from ..configs import load_table
from . import evaluations as ev
from . import statistics as st
from .aggregate import RESULTS_CSV, compare, read_results, sort_key
from .config import EXPERIMENT_FILE, Comparison, config_labels
from .curves import Curve, curves

#: Columns of the across-study CSV.
CSV_COLUMNS = (
    "study", "a", "b", "metric", "direction", "seeds_a", "seeds_b", "effect", "effect_ci_low",
    "effect_ci_high", "min_effect", "p", "p_method", "p_holm", "p_holm_all", "mde", "mde_all",
    "verdict", "verdict_all", "flags", "shared",
)  # fmt: skip


def study_folders(root: Path) -> list[Path]:
    """The folders under `root` (sorted by name) whose experiment.json registers comparisons and that
    hold a results.csv."""
    out = []
    for folder in sorted(p for p in Path(root).iterdir() if p.is_dir()):
        info = folder / EXPERIMENT_FILE
        if (
            (folder / RESULTS_CSV).is_file()
            and info.is_file()
            and json.loads(info.read_text()).get("comparisons")
        ):
            out.append(folder)
    return out


def _arm_fingerprint(curve: Curve) -> str:
    """What identifies an arm's runs: its configuration and every seed's success curve."""
    h = hashlib.sha256(repr((curve.key[:4], curve.seeds, curve.env_steps.tolist())).encode())
    h.update(np.ascontiguousarray(curve.success, dtype=float).tobytes())
    return h.hexdigest()


def study_comparisons(folder: Path) -> list[dict[str, Any]]:
    """A study's comparisons recomputed from its results.csv, evaluations.csv (evaluation-only arms) and
    experiment.json (aggregate.compare), each with `study` and `arm_runs` (its two arms' labels ->
    fingerprints of their runs)."""
    rows = sorted(read_results(folder / RESULTS_CSV), key=sort_key)
    all_curves = curves(rows)
    info = json.loads((folder / EXPERIMENT_FILE).read_text())
    comparisons = tuple(
        load_table(Comparison, c, source=folder / EXPERIMENT_FILE, where=f"comparisons[{i}]")
        for i, c in enumerate(info["comparisons"])
    )
    labels = config_labels([c.key for c in all_curves])
    fingerprints = {label: _arm_fingerprint(c) for label, c in zip(labels, all_curves, strict=True)}
    eval_success = ev.per_seed_success(ev.read_evaluations(folder / ev.EVALUATIONS_CSV))
    for label, values in eval_success.items():  # evaluation-only arms: their per-seed success rates
        fingerprints[label] = hashlib.sha256(repr((folder.name, label, values.tolist())).encode()).hexdigest()
    out = compare(all_curves, comparisons, eval_success)
    for row in out:
        row["study"] = folder.name
        row["arm_runs"] = {arm: fingerprints[arm] for arm in (row["a"], row["b"])}
    return out


def correct_across(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Adds to each comparison row (from study_comparisons) Holm's adjustment over all `rows`
    (`p_holm_all`), the minimum detectable effect at that family's size (`mde_all`), the verdict at it
    (`verdict_all`, statistics.verdict) and `shared`: the arms whose runs another comparison of the
    same metric uses too ("arm with <comparison>" in the same study, "arm with <study>" in another), so
    that the two are not independent replications."""
    family = st.holm([r["p"] for r in rows])
    users: dict[str, list[int]] = defaultdict(list)
    for i, r in enumerate(rows):
        for fingerprint in r["arm_runs"].values():
            users[fingerprint].append(i)
    out = []
    for i, (r, p_all) in enumerate(zip(rows, family, strict=True)):
        effect = st.Estimate(
            np.array([r["effect"]]), np.array([r["effect_ci_low"]]), np.array([r["effect_ci_high"]]),
            np.array([r["effect_sd"]]),
        )  # fmt: skip
        min_effect = None if np.isnan(r["min_effect"]) else float(r["min_effect"])
        mde = st.minimum_detectable_effect(r["effect_sd"], len(rows), r["direction"])
        shared = set()
        for arm, fingerprint in r["arm_runs"].items():
            for j in users[fingerprint]:
                if j != i and rows[j]["metric"] == r["metric"]:
                    other = rows[j]
                    shared.add(
                        f"{arm} with {name(other) if other['study'] == r['study'] else other['study']}"
                    )
        verdict = st.verdict(r["a"], r["b"], effect, float(p_all), mde, r["direction"], min_effect)
        out.append(
            r
            | {
                "p_holm_all": float(p_all),
                "mde_all": mde,
                "verdict_all": verdict,
                "shared": "; ".join(sorted(shared)),
            }
        )
    return out


def name(row: dict[str, Any]) -> str:
    """A comparison as tables name it: "a > b (metric)"."""
    side = {"greater": ">", "less": "<", "two-sided": "vs"}[row["direction"]]
    return f"{row['a']} {side} {row['b']} ({row['metric']})"


def markdown_table(rows: list[dict[str, Any]]) -> list[str]:
    """The across-study table: one line per comparison, the study's Holm beside the family-wide one."""
    m = len(rows)
    header = (
        "| study | comparison | effect [95%] | p (method) | p Holm, study | verdict, study | "
        f"p Holm, all {m} | verdict, all {m} | flags | same runs as |"
    )
    lines = [
        header,
        "| --- | --- | --- | ---: | ---: | --- | ---: | --- | --- | --- |",
    ]
    for r in rows:
        method = {"exact": "exact", "none: every score equal": "none"}.get(r["p_method"], "normal")
        cells = [
            r["study"],
            name(r),
            f"{r['effect']:+.3f} [{r['effect_ci_low']:+.3f}, {r['effect_ci_high']:+.3f}]",
            f"{r['p']:.3g} ({method})",
            f"{r['p_holm']:.3g}",
            r["verdict"],
            f"{r['p_holm_all']:.3g}",
            r["verdict_all"],
            r["flags"],
            r["shared"],
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def across(root: Path) -> list[dict[str, Any]]:
    """Every study's comparisons under `root`, corrected across all of them (correct_across)."""
    return correct_across([r for folder in study_folders(root) for r in study_comparisons(folder)])
