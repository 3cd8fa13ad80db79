"""The 2 x 2 of issue 28's study 1 (experiments/her-strength-{final,future}.toml): HER final k=1 vs
future k=4, crossed with baseline vs fs1, on UR5e reach. From the two rows' committed results.csv
(docs/results/her-strength-final/, -future/; or --root for results/), per cell the IQM AUC and final
success with intervals, the fs1 - baseline effect in each row, and the pre-registered interaction
[IQM_AUC(fs1, future) - IQM_AUC(baseline, future)] - [IQM_AUC(fs1, final) - IQM_AUC(baseline, final)]
with its 95% stratified-bootstrap interval. Only the seeds every cell finished count. Prints markdown.

    python scripts/her_interaction.py [--root docs/results]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from tsrl.experiments import statistics as st
from tsrl.experiments.aggregate import RESULTS_CSV, read_results, sort_key
from tsrl.experiments.curves import curves

ROWS = ("final", "future")
ARMS = ("baseline", "fs1")
RELEVANT = 0.05  # the registered relevant size of the interaction (AUC)


def cells(root: Path) -> dict[tuple[str, str], dict[str, np.ndarray]]:
    """(HER row, arm) -> per-seed metrics over the seeds that every cell has at its full budget."""
    by_cell = {}
    for row in ROWS:
        for c in curves(sorted(read_results(root / f"her-strength-{row}" / RESULTS_CSV), key=sort_key)):
            by_cell[row, c.key[1]] = c
    budget = max(int(c.env_steps[-1]) for c in by_cell.values())
    done = [set(c.seeds) for c in by_cell.values()]
    seeds = sorted(set.intersection(*done))
    out = {}
    for key, c in by_cell.items():
        if int(c.env_steps[-1]) != budget:
            sys.exit(
                f"{key}: its common evaluations end at {c.env_steps[-1]}, not {budget} (a seed unfinished)"
            )
        keep = [c.seeds.index(s) for s in seeds]
        out[key] = {k: v[keep] for k, v in c.seed_metrics().items()} | {"seeds": np.array(seeds)}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1] / "docs" / "results")
    args = parser.parse_args(argv)
    m = cells(args.root)
    n = len(m[ROWS[0], ARMS[0]]["seeds"])
    print(f"Seeds per cell: {n} ({', '.join(map(str, m[ROWS[0], ARMS[0]]['seeds']))}).\n")
    print("| HER | arm | AUC, IQM [95%] | final success, IQM [95%] |")
    print("| --- | --- | --- | --- |")
    for row in ROWS:
        for arm in ARMS:
            cells_text = []
            for metric in ("auc", "final_success"):
                e = st.iqm_interval(m[row, arm][metric])
                cells_text.append(f"{e.point[0]:.2f} [{e.low[0]:.2f}, {e.high[0]:.2f}]")
            print(f"| {row} | {arm} | {' | '.join(cells_text)} |")
    print("\n| HER | fs1 - baseline, AUC [95%] | P(fs1 > baseline) | p (Mann-Whitney, one-sided; method) |")
    print("| --- | --- | --- | --- |")
    for row in ROWS:
        x, y = m[row, "fs1"]["auc"], m[row, "baseline"]["auc"]
        e, poi = st.iqm_difference(x, y), st.probability_of_improvement(x, y)
        p, method = st.mann_whitney_p(x, y, "greater"), st.mann_whitney_method(x, y)
        print(
            f"| {row} | {e.point[0]:+.3f} [{e.low[0]:+.3f}, {e.high[0]:+.3f}] | {poi.point[0]:.2f} | {p:.3g}; {method} |"
        )
    inter = st.interaction(
        m["final", "fs1"]["auc"],
        m["final", "baseline"]["auc"],
        m["future", "fs1"]["auc"],
        m["future", "baseline"]["auc"],
    )
    lo, hi = inter.low[0], inter.high[0]
    decided = (
        "excludes 0: the feature effect depends on HER"
        if hi < 0 or lo > 0
        else "contains 0: no interaction detected"
    )
    relevant = (
        f"; the point estimate's magnitude {abs(inter.point[0]):.3f} is {'at least' if abs(inter.point[0]) >= RELEVANT else 'below'} "
        f"the registered {RELEVANT}"
    )
    print(
        f"\nInteraction (effect under future k=4 minus effect under final k=1, AUC): {inter.point[0]:+.3f} "
        f"[{lo:+.3f}, {hi:+.3f}]; the interval {decided}{relevant}."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
