"""Plots of an experiment: learning curves (eval success rate against env steps; per-seed lines under
the IQM across seeds and its 95% stratified-bootstrap interval, tsrl.experiments.statistics) beside a
strip plot of each seed's AUC, the share of penalised evaluation episodes (tasks with penalties) and
the AUC performance profile.

Every arm has one colour in every figure, derived from its name: the paper's for its Table I presets,
otherwise a colour picked by a hash of the label (the next free one when two arms of a figure would
share it). Legends sit below the axes, never over the data; labels are readable names
(`readable_labels`: "fs1 + obstacle distance", "task space", "joint 0.126 rad"), not spec strings."""

from __future__ import annotations

import hashlib
import re
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import statistics as st
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

#: Readable names of task maps in spec strings (a preset followed by extra terms reads "fs1 + ...").
TERM_NAMES: dict[str, str] = {
    "velocity(position(tcp))": "TCP velocity",
    "velocity(positionDiff(tcp, target))": "TCP-target velocity",
    "distance(suction_cup, obstacle)": "obstacle distance",
    "accumulatedCollisions": "collisions",
    "quaternion(tcp)": "TCP quaternion",
    "quaternionDiff(tcp, target)": "quaternion difference",
    "scalarProductXX(world, tcp)": "scalar products",
    "scalarProductYY(world, tcp)": "scalar products",
    "scalarProductZZ(world, tcp)": "scalar products",
    "positionDiff(box, tcp)": "box-TCP",
    "velocity(position(box))": "box velocity",
    "suction(suction)": "suction",
    "jointState": "joint state",
    "velocity(jointState)": "joint velocity",
    "pick_phi": "phi_1..phi_6",
    "taskspace": "task space",
    "pick_phi_plus": "phi_1..phi_6 + box-TCP + box velocity + suction",
}
#: A task file of the action ablation: joint actions of the given step.
_JOINT_TASK = re.compile(r"^reach-joint-(?P<step>[0-9.]+)$")

#: Legend entries and strip-plot ticks wrap at these many characters.
LEGEND_WIDTH = 48
TICK_WIDTH = 16
TITLE_WIDTH = 100


def _split_terms(spec: str) -> list[str]:
    """The top-level comma-separated terms of a spec string (commas inside parentheses stay)."""
    terms, depth, start = [], 0, 0
    for i, ch in enumerate(spec):
        depth += {"(": 1, ")": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            terms.append(spec[start:i].strip())
            start = i + 1
    return [*terms, spec[start:].strip()]


def readable_label(label: str, task_space: bool = False) -> str:
    """One arm label (config_labels' " / "-joined parts) as a figure names it: spec strings as their
    terms' TERM_NAMES joined by " + " (repeats once), a joint-action task file as "joint <step> rad",
    a registered id without its "tsrl/" prefix, or "task space" when `task_space` (the figure's other
    arms are joint-action tasks)."""
    parts = []
    for part in label.split(" / "):
        joint = _JOINT_TASK.match(part)
        if joint:
            parts.append(f"joint {joint['step']} rad")
        elif part.startswith("tsrl/") and task_space:
            parts.append("task space")
        else:
            names = [TERM_NAMES.get(t, t) for t in _split_terms(part.removeprefix("tsrl/"))]
            parts.append(" + ".join(dict.fromkeys(names)))
    return " / ".join(parts)


def readable_labels(labels: list[str]) -> list[str]:
    """readable_label of each of a figure's labels (the registered reach id reads "task space" when
    the other arms are joint-action task files)."""
    joint = any(_JOINT_TASK.match(p) for label in labels for p in label.split(" / "))
    return [readable_label(label, task_space=joint) for label in labels]


#: Colours of arms that are not Table I presets: distinct hues, none like the paper's blues, orange,
#: red or grey (tab10's green, purple, brown, pink, olive; Dark2's teal and gold; dark magenta; black).
ARM_PALETTE: tuple[str, ...] = (
    "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#1b9e77", "#e6ab02", "#7a0177", "#000000",
)  # fmt: skip


def arm_colour(label: str) -> str:
    """An arm's colour from its label alone: the paper's for a Table I preset, else the palette colour
    a hash (sha256) of the label picks: the same arm in the same colour in every figure."""
    if label in PAPER_COLOURS:
        return PAPER_COLOURS[label]
    return ARM_PALETTE[int(hashlib.sha256(label.encode()).hexdigest(), 16) % len(ARM_PALETTE)]


def colours(curves: list[Curve]) -> list[str]:
    """Each curve's colour: arm_colour of its readable name (its preset's when the curves' presets
    differ, its label's otherwise); a colour a previous curve of the figure took moves to the next free
    palette colour."""
    import matplotlib.colors as mcolors

    presets = [c.key[1] for c in curves]
    names = readable_labels(
        presets if len(set(presets)) == len(presets) else config_labels([c.key for c in curves])
    )
    palette, used, out = ARM_PALETTE, set(), []
    for name in names:
        colour = arm_colour(name)
        if mcolors.to_hex(colour) in used and name not in PAPER_COLOURS:
            start = palette.index(mcolors.to_hex(colour))
            free = [palette[(start + k) % len(palette)] for k in range(len(palette))]
            colour = next((c for c in free if c not in used), colour)
        used.add(mcolors.to_hex(colour))
        out.append(colour)
    return out


def describe(curves: list[Curve], agent: str | None = None) -> str:
    """Task, agent, seeds and evaluation episodes of `curves`, e.g. "UR5eReach-v0, DDPG + HER (final,
    1 relabelled), 10 seeds, 50 eval episodes"; `agent` replaces the default "<ALGO> + HER"."""

    def joined(values: set) -> str:
        return "/".join(map(str, sorted(values)))

    envs = joined({env_label(c.key[0]).removeprefix("tsrl/") for c in curves})
    algos = agent or f"{joined({c.key[3].upper() for c in curves})} + HER"
    seeds = {len(c.seeds) for c in curves}
    n = f"{min(seeds)}-{max(seeds)}" if len(seeds) > 1 else str(seeds.pop())
    episodes = joined({e for c in curves for e in c.eval_episodes if e})
    text = f"{envs}, {algos}, {n} seed{'s' if n != '1' else ''}" + (
        f", {episodes} eval episodes" if episodes else ""
    )
    return textwrap.fill(text, TITLE_WIDTH)


def describe_agent(info: dict[str, Any]) -> str | None:
    """The agent of an experiment.json as titles name it: "DDPG + HER (final, 1 relabelled copy) + 100
    demonstrations"; None without one."""
    algos = info.get("algo")
    if not algos:
        return None
    text = f"{'/'.join(a.upper() for a in algos)} + HER"
    her = (info.get("agent") or {}).get("her") or {}
    if her.get("strategy"):
        k = her.get("n_sampled_goal", 1)
        text += f" ({her['strategy']}, {k} relabelled cop{'y' if k == 1 else 'ies'})"
    demos = info.get("demos")
    if demos:
        text += f" + {demos['episodes']} demonstrations"
    return text


def _threshold_lines(ax: Any) -> None:
    """Dashed lines at the success thresholds, each labelled at the axes' right edge."""
    for threshold in THRESHOLDS:
        ax.axhline(threshold, color="black", linestyle="--", linewidth=0.7, alpha=0.5)
        ax.text(
            1.005, threshold, f"{threshold:.0%}", transform=ax.get_yaxis_transform(), va="center",
            ha="left", fontsize=7, alpha=0.8,
        )  # fmt: skip


def _legend_below(fig: Any, ax: Any, n: int) -> None:
    """The figure's legend under the axes (never over the data)."""
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(3, n), fontsize=8, frameon=False)


def _save(fig: Any, out: Path, rows_of_legend: int) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout(rect=(0, 0.06 * rows_of_legend, 1, 1))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out


def _legend_rows(labels: list[str]) -> int:
    return -(-len(labels) // 3) + max(label.count("\n") for label in labels)


def _strip(ax: Any, values: list[np.ndarray], labels: list[str], cols: list[str], ylabel: str) -> None:
    """Per arm, each seed's value as a dot (spread evenly across the arm's slot) and the IQM with its
    95% stratified-bootstrap interval as a bar."""
    for i, (v, colour) in enumerate(zip(values, cols, strict=True)):
        spread = np.linspace(-0.2, 0.2, len(v)) if len(v) > 1 else np.zeros(1)
        ax.scatter(i + spread, np.sort(v), s=12, color=colour, alpha=0.7, linewidths=0)
        est = st.iqm_interval(v)
        ax.errorbar(
            [i], est.point, yerr=[[est.point[0] - est.low[0]], [est.high[0] - est.point[0]]], fmt="_",
            color="black", markersize=14, capsize=3, linewidth=1,
        )  # fmt: skip
    ticks = [
        "\n".join(textwrap.fill(part, TICK_WIDTH, break_long_words=False) for part in label.split(" / "))
        for label in labels
    ]  # a variant (" / key=value") on a line of its own
    slanted = len(labels) > 2
    ax.set_xticks(
        range(len(labels)),
        ticks,
        fontsize=7,
        rotation=40 if slanted else 0,
        ha="right" if slanted else "center",
        rotation_mode="anchor" if slanted else "default",  # a wrapped label turns as one block
    )
    ax.set_xlim(-0.6, len(labels) - 0.4)
    ax.set_ylim(-0.02, 1.02)
    ax.set_ylabel(ylabel, fontsize=8)
    ax.grid(alpha=0.3, axis="y")


def _curve_figure(
    curves: list[Curve],
    values: list[np.ndarray],
    ylabel: str,
    strip_label: str,
    title: str,
    out: Path,
    thresholds: bool,
) -> Path:
    """Curves of `values` (per curve, (n seeds, m) against its env steps) beside a strip plot of each
    seed's area under them (`strip_label`); `thresholds`: the success thresholds drawn."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = readable_labels(config_labels([c.key for c in curves]))
    cols = colours(curves)
    fig, (ax, strip) = plt.subplots(
        1, 2, figsize=(10, 4.8), dpi=120, gridspec_kw={"width_ratios": [3, max(1.0, 0.35 * len(curves))]}
    )
    legends = []
    for curve, v, label, colour in zip(curves, values, labels, cols, strict=True):
        xs = curve.env_steps
        for seed_curve in v:
            ax.plot(xs, seed_curve, color=colour, linewidth=0.5, alpha=0.3)
        est = st.iqm_interval(v)
        n = len(curve.seeds)
        legends.append(textwrap.fill(f"{label} ({n} seed{'s' if n > 1 else ''})", LEGEND_WIDTH))
        ax.plot(xs, est.point, color=colour, linewidth=2, label=legends[-1])
        if n > 1:
            ax.fill_between(xs, est.low, est.high, color=colour, alpha=0.2, linewidth=0)
    if thresholds:
        _threshold_lines(ax)
    ax.set_xlabel("env steps")
    ax.set_ylabel(ylabel)
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.set_title(title, fontsize=9)
    aucs = [
        st.area_under_curve(c.env_steps, v) if len(c.env_steps) > 1 else v[:, -1]
        for c, v in zip(curves, values, strict=True)
    ]
    _strip(strip, aucs, labels, cols, strip_label)
    strip.set_title("per seed; bar: IQM [95%]", fontsize=8)
    _legend_below(fig, ax, len(curves))
    return _save(fig, out, _legend_rows(legends))


def plot_curves(curves: list[Curve], out: Path, name: str | None = None, agent: str | None = None) -> Path:
    """Writes a PNG of `curves` against env steps (thin per-seed lines, the IQM across seeds and its
    interval, labelled dashed lines at the success thresholds) beside a strip plot of each seed's AUC.
    `agent` names the agent in the title (describe_agent)."""
    title = f"{describe(curves, agent)}\nIQM across seeds, 95% stratified-bootstrap interval; thin: seeds"
    return _curve_figure(
        curves,
        [c.success for c in curves],
        "eval success rate",
        "AUC (area under the success curve)",
        f"{name}\n{title}" if name else title,
        out,
        thresholds=True,
    )


def plot_penalised(curves: list[Curve], out: Path, name: str, agent: str | None = None) -> Path:
    """Writes the share of evaluation episodes with a penalised step (e.g. touching the obstacle)
    against env steps, as plot_curves draws success, beside a strip plot of each seed's area under it."""
    title = (
        f"{name}\n{describe(curves, agent)}\nshare of evaluation episodes with a penalised step "
        "(obstacle reach: touching the obstacle); IQM [95%]"
    )
    values = [c.penalised if c.penalised is not None else np.full(c.success.shape, np.nan) for c in curves]
    return _curve_figure(
        curves, values, "penalised episodes (share)", "area under the penalised share", title, out, False
    )


def plot_profile(
    profile: dict[str, Estimate],
    taus: np.ndarray,
    curves: list[Curve],
    out: Path,
    name: str,
    agent: str | None = None,
) -> Path:
    """Writes the AUC performance profile: per arm, the fraction of seeds with AUC above tau, with its
    interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=120)
    labels = [textwrap.fill(label, LEGEND_WIDTH) for label in readable_labels(list(profile))]
    for (_, est), label, colour in zip(profile.items(), labels, colours(curves), strict=True):
        ax.plot(taus, est.point, color=colour, linewidth=2, label=label)
        ax.fill_between(taus, est.low, est.high, color=colour, alpha=0.2, linewidth=0)
    ax.set_xlabel("AUC threshold tau (normalised area under the success curve)")
    ax.set_ylabel("fraction of seeds with AUC > tau")
    ax.set_ylim(-0.02, 1.02)
    ax.grid(alpha=0.3)
    ax.set_title(
        f"{name}\n{describe(curves, agent)}\nAUC performance profile, 95% stratified-bootstrap interval",
        fontsize=9,
    )
    _legend_below(fig, ax, len(labels))
    return _save(fig, out, _legend_rows(labels))
