"""Milestones of saved runs, for the studies' tables: env steps and seconds to 50/90/95 % evaluation
success per seed, means with their Student-t intervals, and AUCs over the evaluations every run has.

Reads only each run's progress.csv and config.json (RUN_FILES), so that a study's table re-derives
from the copies `save_runs` commits (<data folder>/<group>/<run name>/).
"""

from __future__ import annotations

import csv
import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

#: Evaluation success levels of the milestone tables.
THRESHOLDS = (0.5, 0.9, 0.95)
#: A run folder's files that its tables are made of.
RUN_FILES = ("progress.csv", "config.json")


def read_progress_csv(run_dir: Path) -> list[dict[str, float]]:
    """A run's progress.csv rows, every column a float (an empty cell NaN)."""
    with open(run_dir / "progress.csv", newline="") as f:
        return [{k: float(v) if v != "" else math.nan for k, v in r.items()} for r in csv.DictReader(f)]


def run_seed(run_dir: Path) -> int:
    """The seed in a run's config.json."""
    return int(json.loads((run_dir / "config.json").read_text())["seed"])


def save_runs(run_dirs: list[Path], out: Path, group: Callable[[Path], str] | None = None) -> None:
    """Copies each run's RUN_FILES to out/<group(run folder), default its parent folder's name>/<run name>/."""
    for run_dir in run_dirs:
        dest = out / (group(run_dir) if group else run_dir.parent.name) / run_dir.name
        dest.mkdir(parents=True, exist_ok=True)
        for name in RUN_FILES:
            shutil.copyfile(run_dir / name, dest / name)


def saved_runs(data_dir: Path) -> list[Path]:
    """The run folders under `data_dir` (as `save_runs` lays them out), sorted by path."""
    return sorted(p.parent for p in data_dir.glob("*/*/progress.csv"))


def first_reaching(
    rows: list[dict[str, float]], threshold: float, train_time: bool = False
) -> tuple[float, float]:
    """(env steps, wall time s) of the first evaluation with success >= threshold; NaN if none.

    With `train_time`, the wall time leaves the evaluations out.
    """
    for r in rows:
        if r["eval_success_rate"] >= threshold:
            return r["env_steps"], r["wall_time_s"] - (r["eval_time_s"] if train_time else 0.0)
    return math.nan, math.nan


def mean_ci95(values: np.ndarray) -> tuple[float, float]:
    """Mean over seeds and the half-width of its 95% Student-t interval (0 for one seed). Learning
    curves and studies use the IQM and bootstrap interval of tsrl.experiments.statistics."""
    from scipy.stats import t

    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return float(values.mean()), 0.0
    sem = values.std(ddof=1) / math.sqrt(len(values))
    return float(values.mean()), float(t.ppf(0.975, len(values) - 1) * sem)


def steps_text(x: float) -> str:
    """Env steps as the tables write them: "never" where not reached."""
    return "never" if not math.isfinite(x) else f"{x:,.0f}"


def whole_text(x: float) -> str:
    """A whole number as the tables write it: "-" where there is none."""
    return "-" if not math.isfinite(x) else f"{x:.0f}"


def common_aucs(
    curves: dict[str, list[list[dict[str, float]]]],
) -> tuple[list[float], dict[str, np.ndarray]]:
    """(the env steps at which every run of every variant was evaluated, per variant its seeds' AUC
    over those evaluations (n seeds,)); curves: variant -> its runs' progress rows."""
    from . import statistics as st

    steps = sorted(set.intersection(*({r["env_steps"] for r in c} for cs in curves.values() for c in cs)))
    aucs = {
        v: st.area_under_curve(
            np.array(steps),
            np.array([[{r["env_steps"]: r["eval_success_rate"] for r in c}[x] for x in steps] for c in cs]),
        )
        for v, cs in curves.items()
    }
    return steps, aucs
