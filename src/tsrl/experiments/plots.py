"""Learning curves of an experiment: eval success rate vs episodes or env steps, one colour per
configuration, mean across seeds with its 95% interval (computed by tsrl.experiments.aggregate, which
calls this module; nothing here imports it)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal, Protocol

import numpy as np

from ..agents.plotting import save_success_plot
from .config import Key, config_labels


class Curve(Protocol):
    """What a learning curve offers the plot (tsrl.experiments.aggregate.Curve has it)."""

    key: Key
    seeds: tuple[int, ...]
    env_steps: np.ndarray
    episodes: np.ndarray

    def stats(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mean, low and high of the interval across seeds at each evaluation."""
        ...


def plot_curves(curves: list[Curve], x: Literal["episodes", "env_steps"], out: Path, title: str) -> Path:
    """Writes a PNG of `curves` against training episodes (as the paper plots) or env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = config_labels([c.key for c in curves])
    colours = plt.get_cmap("tab10" if len(curves) <= 10 else "tab20").colors
    fig, ax = plt.subplots(figsize=(7, 4.2), dpi=120)
    for i, (curve, label) in enumerate(zip(curves, labels, strict=True)):
        xs = curve.episodes if x == "episodes" else curve.env_steps
        mean, low, high = curve.stats()
        n = len(curve.seeds)
        colour = colours[i % len(colours)]
        ax.plot(
            xs,
            mean,
            color=colour,
            label=f"{label} ({n} seed{'s' if n > 1 else ''})",
            marker="." if len(xs) < 30 else None,
        )
        if n > 1:
            ax.fill_between(xs, low, high, color=colour, alpha=0.2, linewidth=0)
    return save_success_plot(
        fig,
        ax,
        out,
        xlabel="training episodes" if x == "episodes" else "env steps",
        title=f"{title}: mean and 95% bootstrap CI across seeds",
        fontsize=10,
    )
