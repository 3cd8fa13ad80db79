"""Plots of an experiment: learning curves (eval success rate against env steps; per-seed lines under
the IQM across seeds and its 95% stratified-bootstrap interval, tsrl.experiments.statistics) and the
AUC performance profile. Observation presets get the paper's colours, in its Table I order."""

from __future__ import annotations

import itertools
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..agents.plotting import save_success_plot
from .config import config_labels, env_label
from .statistics import THRESHOLDS

if TYPE_CHECKING:
    from .curves import Curve
    from .statistics import Estimate

#: The paper's colours of the Table I presets.
PAPER_COLOURS: dict[str, str] = {
    "baseline": "tab:orange",
    "simple": "tab:red",
    "fs0": "#08306b",  # dark blue
    "fs1": "#6baed6",  # light blue
    "fs2": "tab:grey",
}

#: Legend entries (spec strings can be long) wrap at this many characters.
LEGEND_WIDTH = 60


def colours(curves: list[Curve]) -> list[str]:
    """Each curve's colour: the paper's for a Table I preset (when no two curves share the preset), the
    next tab10/tab20 colour the paper's presets do not use for anything else."""
    import matplotlib.colors as mcolors
    import matplotlib.pyplot as plt

    presets = [c.key[1] for c in curves]
    distinct = len(set(presets)) == len(presets)
    taken = {mcolors.to_hex(c) for c in PAPER_COLOURS.values()} if distinct else set()
    cycle = plt.get_cmap("tab10" if len(curves) <= 10 else "tab20").colors
    free = itertools.cycle([c for c in cycle if mcolors.to_hex(c) not in taken])
    return [PAPER_COLOURS[p] if distinct and p in PAPER_COLOURS else next(free) for p in presets]


def describe(curves: list[Curve]) -> str:
    """Task, algorithm, seeds and evaluation episodes of `curves`, e.g. "UR5eReach-v0, DDPG + HER,
    10 seeds, 50 eval episodes"."""

    def joined(values: set) -> str:
        return "/".join(map(str, sorted(values)))

    envs = joined({env_label(c.key[0]).removeprefix("tsrl/") for c in curves})
    algos = joined({c.key[3].upper() for c in curves})
    seeds = {len(c.seeds) for c in curves}
    n = f"{min(seeds)}-{max(seeds)}" if len(seeds) > 1 else str(seeds.pop())
    episodes = joined({e for c in curves for e in c.eval_episodes})
    return f"{envs}, {algos} + HER, {n} seed{'s' if n != '1' else ''}, {episodes} eval episodes"


def plot_curves(curves: list[Curve], out: Path, name: str | None = None) -> Path:
    """Writes a PNG of `curves` against env steps: thin per-seed lines, the IQM across seeds and its
    interval, dashed lines at the success thresholds."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=120)
    for curve, label, colour in zip(
        curves, config_labels([c.key for c in curves]), colours(curves), strict=True
    ):
        xs = curve.env_steps
        for seed_curve in curve.success:
            ax.plot(xs, seed_curve, color=colour, linewidth=0.5, alpha=0.3)
        est = curve.stats()
        n = len(curve.seeds)
        legend = textwrap.fill(f"{label} ({n} seed{'s' if n > 1 else ''})", LEGEND_WIDTH)
        ax.plot(xs, est.point, color=colour, linewidth=2, label=legend)
        if n > 1:
            ax.fill_between(xs, est.low, est.high, color=colour, alpha=0.2, linewidth=0)
    for threshold in THRESHOLDS:
        ax.axhline(threshold, color="black", linestyle="--", linewidth=0.7, alpha=0.5)
    title = f"{describe(curves)}\nIQM across seeds, 95% stratified-bootstrap interval; thin: seeds"
    return save_success_plot(
        fig, ax, out, xlabel="env steps", title=f"{name}\n{title}" if name else title, fontsize=9
    )


def plot_profile(
    profile: dict[str, Estimate], taus: np.ndarray, curves: list[Curve], out: Path, name: str
) -> Path:
    """Writes the AUC performance profile: per arm, the fraction of seeds with AUC above tau, with its
    interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=120)
    for (label, est), colour in zip(profile.items(), colours(curves), strict=True):
        ax.plot(taus, est.point, color=colour, linewidth=2, label=textwrap.fill(label, LEGEND_WIDTH))
        ax.fill_between(taus, est.low, est.high, color=colour, alpha=0.2, linewidth=0)
    ax.set_xlabel("AUC threshold tau (normalised area under the success curve)")
    ax.set_ylabel("fraction of seeds with AUC > tau")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(
        f"{name}\n{describe(curves)}\nAUC performance profile, 95% stratified-bootstrap interval", fontsize=9
    )
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
