"""Learning curves of runs: evaluation success rate against env steps, mean and 95% CI across seeds."""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .run_folder import load_config, read_progress

#: Two-sided 95% Student-t quantiles by degrees of freedom (1..10); 1.96 beyond.
_T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306, 9: 2.262, 10: 2.228}


def mean_ci95(values: np.ndarray) -> tuple[float, float]:
    """Mean and half-width of its 95% confidence interval (Student t; 0 for a single value)."""
    values = np.asarray(values, dtype=float)
    n = len(values)
    if n < 2:
        return float(values.mean()), 0.0
    sem = values.std(ddof=1) / math.sqrt(n)
    return float(values.mean()), float(_T95.get(n - 1, 1.96) * sem)


def plot_learning_curves(run_dirs: Sequence[Path], out: Path, title: str | None = None) -> Path:
    """Writes a PNG: one line per (env, obs, action, algo) group of runs, mean and 95% CI over seeds.

    Runs of a group are aligned on their evaluation env steps (the steps all of them reached).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[str, list[list[dict[str, float]]]] = defaultdict(list)
    for run_dir in run_dirs:
        cfg = load_config(Path(run_dir))
        label = f"{cfg.obs} / {cfg.action} / {cfg.agent.algo}"
        if cfg.agent.her.relabel != "feature":
            label += f" / HER {cfg.agent.her.relabel}"
        rows = read_progress(run_dir)
        if rows:
            groups[label].append(rows)

    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    for label, runs in groups.items():
        common = sorted(set.intersection(*({int(r["env_steps"]) for r in rows} for rows in runs)))
        if not common:
            continue
        by_step = [{int(r["env_steps"]): r["eval_success_rate"] for r in rows} for rows in runs]
        stats = np.array([mean_ci95(np.array([run[s] for run in by_step])) for s in common])
        ax.plot(common, stats[:, 0], label=f"{label} ({len(runs)} seed{'s' if len(runs) > 1 else ''})")
        if len(runs) > 1:
            ax.fill_between(common, stats[:, 0] - stats[:, 1], stats[:, 0] + stats[:, 1], alpha=0.2)
    if title is None and run_dirs:
        title = load_config(Path(run_dirs[0])).env_id
    return save_success_plot(fig, ax, out, xlabel="env steps", title=title)


def save_success_plot(
    fig: Any, ax: Any, out: Path, xlabel: str, title: str | None, fontsize: int = 12
) -> Path:
    """Labels a success-rate axes (y in [0, 1], grid, legend), writes the PNG to `out` and closes `fig`."""
    import matplotlib.pyplot as plt

    ax.set_xlabel(xlabel)
    ax.set_ylabel("eval success rate")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    if title:
        ax.set_title(title, fontsize=fontsize)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
