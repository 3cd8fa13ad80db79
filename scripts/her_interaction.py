"""Issue 28's study 1: HER final k=1 vs future k=4, crossed with the reach presets (baseline, fs1, fs0),
on the 5 cm UR5e reach and the 2 cm reach. Each cell's runs come from one committed study folder
(CELLS: the 5 cm rows are experiments/her-strength-{final,future}.toml and her-strength-fs0-future.toml
with paper-observations-v2's fs0 as the final row's fs0; the 2 cm rows are paper-observations-v2-hard
and her-strength-2cm-future), read on the evaluations common to every cell of the task and on the
seeds every cell finished. Per task and cell the IQM AUC and final success with intervals, each
feature arm's effect over the baseline in each row (Holm over the task's feature arms within a row),
and the pre-registered interactions
[IQM_AUC(f, future) - IQM_AUC(baseline, future)] - [IQM_AUC(f, final) - IQM_AUC(baseline, final)]
with their 95% stratified-bootstrap intervals. Prints markdown.

--check-reuse checks what reusing other studies' runs rests on: the pairs of committed folders in
SAME_RUNS hold equal evaluations at every common env step, and each RUN_DIR given after it (a re-run
of a reused study's run on today's code, e.g. `tsrl experiment` on a one-seed copy of its file) equals
the committed evaluations of that study (`--check-reuse paper-observations-v2-hard=results/x/run`).

    python scripts/her_interaction.py [--root studies] [--check-reuse [STUDY=RUN_DIR ...]]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np
from study_folders import STUDIES, screen_folder

from tsrl.experiments import statistics as st
from tsrl.experiments.aggregate import RESULTS_CSV, collect, read_results, sort_key
from tsrl.experiments.curves import curves

ROWS = ("final", "future")
BASELINE = "baseline"
#: Per reach task: (HER row, arm) -> the committed study folder whose runs of that arm are the cell.
CELLS: dict[str, dict[tuple[str, str], str]] = {
    "5 cm": {
        ("final", "baseline"): "her-strength-final",
        ("final", "fs1"): "her-strength-final",
        ("final", "fs0"): "paper-observations-v2",
        ("future", "baseline"): "her-strength-future",
        ("future", "fs1"): "her-strength-future",
        ("future", "fs0"): "her-strength-fs0-future",
    },
    "2 cm": {
        (row, arm): study
        for row, study in (("final", "paper-observations-v2-hard"), ("future", "her-strength-2cm-future"))
        for arm in ("baseline", "fs1", "fs0")
    },
}
#: Folders with the same runs (same configuration and seeds, other evaluation grid): (a, b, arms).
SAME_RUNS = (
    ("her-strength-final", "paper-observations-v2", ("baseline", "fs1")),
    ("her-strength-fs0-future", "her-strength-future", ("baseline",)),
)
RELEVANT = 0.05  # the registered relevant size of an interaction and of a feature effect (AUC)


def committed(root: Path, study: str) -> list[dict[str, Any]]:
    """The tidy result rows of a committed study folder, root/<question>/<study>/ (exit with one line if it
    has none)."""
    path = screen_folder(study, root) / RESULTS_CSV
    if not path.is_file():
        sys.exit(f"{path}: missing (the study has not run, or `tsrl report` was not run on it)")
    return read_results(path)


def evaluations(rows: list[dict[str, Any]]) -> dict[tuple[str, int, int], float]:
    """(arm, seed, env steps) -> evaluation success of tidy result rows."""
    return {(r["obs"], r["seed"], r["env_steps"]): r["eval_success_rate"] for r in rows}


def differing(a: dict[tuple[str, int, int], float], b: dict[tuple[str, int, int], float]) -> tuple[int, list]:
    """(evaluations a and b share, the shared ones whose success differs)."""
    common = sorted(set(a) & set(b))
    return len(common), [k for k in common if a[k] != b[k]]


def check_reuse(root: Path, reruns: list[str]) -> int:
    """Prints each check of the reuse; 1 when one fails."""
    failed = 0
    for x, y, arms in SAME_RUNS:
        a, b = (evaluations(committed(root, s)) for s in (x, y))
        a = {k: v for k, v in a.items() if k[0] in arms}
        n, bad = differing(a, b)
        failed += bool(bad) or n == 0
        print(f"{x} vs {y} ({', '.join(arms)}): {n} common evaluations, {len(bad)} differ {bad[:3]}")
    for item in reruns:
        study, _, run_dir = item.partition("=")
        n, bad = differing(evaluations(collect([Path(run_dir)])), evaluations(committed(root, study)))
        failed += bool(bad) or n == 0
        print(f"{run_dir} vs {study}: {n} common evaluations, {len(bad)} differ {bad[:3]}")
    print("reuse: " + ("FAILED" if failed else "every check equal"))
    return int(bool(failed))


def cells(root: Path, task: str) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """(HER row, arm) -> per-seed metrics on the evaluations and seeds common to every cell of `task`."""
    rows = {}
    for cell, study in CELLS[task].items():
        rows[cell] = [r for r in committed(root, study) if r["obs"] == cell[1]]
        if not rows[cell]:
            sys.exit(f"{root / study / RESULTS_CSV}: no runs of {cell[1]}")
    runs = {cell: {(r["seed"], r["env_steps"]) for r in rs} for cell, rs in rows.items()}
    seeds = sorted(set.intersection(*({s for s, _ in v} for v in runs.values())))
    steps = sorted(set.intersection(*({t for _, t in v} for v in runs.values())))
    out = {}
    for cell, rs in rows.items():
        keep = [r for r in sorted(rs, key=sort_key) if r["seed"] in seeds and r["env_steps"] in steps]
        (curve,) = curves(keep)
        if list(curve.env_steps) != steps:
            sys.exit(f"{task} {cell}: a seed lacks some of the common evaluations (a run unfinished)")
        out[cell] = curve.seed_metrics() | {"seeds": np.array(seeds), "steps": np.array(steps)}
    return out


def interval(e: st.Estimate, fmt: str = ".2f") -> str:
    """'point [low, high]' of a one-value estimate."""
    return f"{e.point[0]:{fmt}} [{e.low[0]:{fmt}}, {e.high[0]:{fmt}}]"


def report(root: Path, task: str) -> None:
    """Prints the task's 2 x 2 (x 3 arms) tables and the interactions' verdicts."""
    m = cells(root, task)
    arms = list(dict.fromkeys(arm for _, arm in CELLS[task]))
    features = [a for a in arms if a != BASELINE]
    first = m[ROWS[0], BASELINE]
    steps = first["steps"]
    print(f"## Reach {task}\n")
    gaps = set(np.diff(steps).tolist())
    grid = f"every {gaps.pop()}" if len(gaps) == 1 else "unevenly spaced"
    print(
        f"Seeds per cell: {len(first['seeds'])} ({', '.join(map(str, first['seeds']))}); "
        f"{len(steps)} evaluations common to every cell (0 to {steps[-1]:,} env steps, {grid}).\n"
    )
    print("| HER | arm | AUC, IQM [95%] | final success, IQM [95%] |")
    print("| --- | --- | --- | --- |")
    for row in ROWS:
        for arm in arms:
            auc, final = (st.iqm_interval(m[row, arm][k]) for k in ("auc", "final_success"))
            print(f"| {row} | {arm} | {interval(auc)} | {interval(final)} |")
    print(
        "\n| HER | effect, AUC [95%] | P(arm > baseline) | p (Mann-Whitney, one-sided; method) | Holm p (row) |"
    )
    print("| --- | --- | --- | --- | --- |")
    for row in ROWS:
        y = m[row, BASELINE]["auc"]
        ps = [st.mann_whitney_p(m[row, f]["auc"], y, "greater") for f in features]
        for f, p, p_holm in zip(features, ps, st.holm(ps), strict=True):
            x = m[row, f]["auc"]
            e, poi = st.iqm_difference(x, y), st.probability_of_improvement(x, y)
            print(
                f"| {row} | {f} - baseline: {interval(e, '+.3f')} | {poi.point[0]:.2f} | "
                f"{p:.3g}; {st.mann_whitney_method(x, y)} | {p_holm:.3g} |"
            )
    print()
    for f in features:
        inter = st.interaction(
            m["final", f]["auc"],
            m["final", BASELINE]["auc"],
            m["future", f]["auc"],
            m["future", BASELINE]["auc"],
        )
        lo, hi = inter.low[0], inter.high[0]
        decided = (
            "excludes 0: the feature effect depends on HER"
            if hi < 0 or lo > 0
            else "contains 0: no interaction detected"
        )
        size = "at least" if abs(inter.point[0]) >= RELEVANT else "below"
        print(
            f"- Interaction, {f} (effect under future k=4 minus effect under final k=1, AUC): {interval(inter, '+.3f')}; "
            f"the interval {decided}; the point estimate's magnitude {abs(inter.point[0]):.3f} is {size} the registered {RELEVANT}."
        )
    print()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=STUDIES)
    parser.add_argument("--task", choices=sorted(CELLS), action="append", help="default: both")
    parser.add_argument("--check-reuse", nargs="*", metavar="STUDY=RUN_DIR", default=None)
    args = parser.parse_args(argv)
    if args.check_reuse is not None:
        return check_reuse(args.root, args.check_reuse)
    for task in args.task or list(CELLS):
        report(args.root, task)
    return 0


if __name__ == "__main__":
    sys.exit(main())
