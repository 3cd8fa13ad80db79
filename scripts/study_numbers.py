"""The numbers a study's README quotes in its result lines (the lines under its `## Result` heading),
checked against its screens' data (make reproduce-check, through readme_comparisons.py --check):
every interval `X [L, H]` must be, at the decimals it is quoted with, the effect of one of the
question's re-derived comparisons or an IQM cell of one of its screens (summary.md, and
evaluations_summary.csv's success), and every `p = X` one of its comparisons' p, Holm p within the
study or Holm p across all studies. A study folder is studies/<question>/ with screen folders in it."""

from __future__ import annotations

import csv
import re
from pathlib import Path
from typing import Any

from study_folders import STUDIES

RESULT_HEADING = "## Result"
NUMBER = r"[+-]?\d+\.\d+"
INTERVAL = re.compile(rf"(?P<x>{NUMBER}) \[(?P<low>{NUMBER}), (?P<high>{NUMBER})\]")
P_VALUE = re.compile(r"\bp = (?P<p>\d+(?:\.\d+)?(?:e-\d+)?)")


def result_lines(readme: Path) -> list[str] | None:
    """The lines under the README's RESULT_HEADING up to its next `## ` heading; None without one."""
    lines = readme.read_text(encoding="utf-8").splitlines()
    if RESULT_HEADING not in lines:
        return None
    start = lines.index(RESULT_HEADING) + 1
    end = next((i for i in range(start, len(lines)) if lines[i].startswith("## ")), len(lines))
    return lines[start:end]


def matches(quoted: str, value: float) -> bool:
    """Whether `value` rounds to the number `quoted` at the decimals `quoted` is written with."""
    decimals = len(quoted.partition(".")[2].partition("e")[0])
    scale = 10 ** -int(quoted.partition("e-")[2]) if "e-" in quoted else 1.0
    return abs(value - float(quoted)) <= 0.5 * 10**-decimals * scale + 1e-12


def screen_intervals(screen: Path) -> list[tuple[float, float, float]]:
    """The IQM [95 %] cells of a screen's summary.md and its evaluations' success (evaluations_summary.csv)."""
    out = []
    summary = screen / "summary.md"
    if summary.is_file():
        out += [
            tuple(float(m[k]) for k in ("x", "low", "high")) for m in INTERVAL.finditer(summary.read_text())
        ]
    evaluations = screen / "evaluations_summary.csv"
    if evaluations.is_file():
        with open(evaluations, newline="") as f:
            for r in csv.DictReader(f):
                out.append((float(r["success_iqm"]), float(r["success_ci_low"]), float(r["success_ci_high"])))
    return out  # type: ignore[return-value]


def problems(question: Path, rows: list[dict[str, Any]]) -> list[str]:
    """One line per quoted number of question/README.md that its data do not give (rows: every study's
    re-derived comparisons, tsrl.experiments.across)."""
    readme = question / "README.md"
    screens = sorted(p.parent for p in question.glob("*/results.csv"))
    if not readme.is_file():
        return [f"{question}: no README.md"]
    lines = result_lines(readme)
    if lines is None:
        return [f"{readme}: no {RESULT_HEADING!r} section"]
    names = {s.name for s in screens}
    own = [r for r in rows if r["study"] in names]
    triples = [(r["effect"], r["effect_ci_low"], r["effect_ci_high"]) for r in own]
    triples += [t for s in screens for t in screen_intervals(s)]
    p_values = [r[k] for r in own for k in ("p", "p_holm", "p_holm_all")]
    found = []
    for line in lines:
        for m in INTERVAL.finditer(line):
            if not any(all(matches(m[k], v) for k, v in zip(("x", "low", "high"), t)) for t in triples):
                found.append(
                    f"{readme}: {m[0]!r} is no comparison's effect and no IQM cell of {sorted(names)}"
                )
        for m in P_VALUE.finditer(line):
            if not any(matches(m["p"], v) for v in p_values):
                found.append(f"{readme}: 'p = {m['p']}' is no p of the comparisons of {sorted(names)}")
    return found


def check(rows: list[dict[str, Any]], root: Path = STUDIES) -> list[str]:
    """problems() of every study folder under root that holds screens."""
    questions = sorted({p.parent.parent for p in root.glob("*/*/results.csv")})
    return [line for q in questions for line in problems(q, rows)]
