"""Learning curves of single runs (evaluation success rate against env steps) and the success-rate axes
every learning-curve plot shares.

Statistics across seeds (the IQM and its stratified-bootstrap interval) have one home,
tsrl.experiments.statistics, drawn by `tsrl plot` and `tsrl report` (tsrl.experiments.plots); a plot
here shows each run as it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from .config import BC
from .run_folder import load_config, read_progress


def plot_learning_curves(run_dirs: Sequence[Path], out: Path, title: str | None = None) -> Path:
    """Writes a PNG with one line per run: its evaluation success rate at each evaluation's env steps
    (a behaviour-cloning run's: gradient steps).

    The title defaults to the first run's environment id; runs without evaluations are left out.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    clocks = set()
    for run_dir in run_dirs:
        rows = read_progress(run_dir)
        if not rows:
            continue
        cfg = load_config(Path(run_dir))
        label = f"{cfg.obs} / {cfg.action} / {cfg.agent.algo}"
        if cfg.agent.her.relabel != "feature":
            label += f" / HER {cfg.agent.her.relabel}"
        clock = "gradient_steps" if cfg.agent.algo == BC else "env_steps"  # BC takes no env step
        clocks.add(clock)
        steps = [int(r[clock]) for r in rows]
        ax.plot(steps, [r["eval_success_rate"] for r in rows], label=f"{label} (seed {cfg.seed})")
    if title is None and run_dirs:
        title = load_config(Path(run_dirs[0])).env_id
    xlabel = " / ".join(sorted(c.replace("_", " ") for c in clocks)) or "env steps"
    return save_success_plot(fig, ax, out, xlabel=xlabel, title=title)


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
