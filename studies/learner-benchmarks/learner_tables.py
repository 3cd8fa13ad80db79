"""The learner benchmarks' tables (learning.py beside this file; studies/learner-benchmarks/README.md)
from saved run folders: env steps and seconds to 50/90/95 % evaluation success per seed and the mean
with its 95% Student-t interval (tsrl.experiments.milestones), and the suites' verdict lines.
scripts/benchmark_tables.py re-derives the committed ones from docs/results/benchmarks/NAME/<group>/<run>/.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from tsrl.experiments.milestones import (
    THRESHOLDS,
    common_aucs,
    first_reaching,
    mean_ci95,
    read_progress_csv,
    run_seed,
    saved_runs,
    steps_text,
    whole_text,
)

PANDA = "tsrl/PandaReach-v0"
UR5E = "tsrl/UR5eReach-v0"
#: The own-robot target: every seed at this evaluation success within the budget.
OWN_ROBOT_TARGET = 0.9
#: Issue 27's reach target: every seed at 95 % evaluation success within this many env steps.
REACH_TARGET_STEPS = 1_000
#: Issue 27's pick-and-place target: every seed at 95 % evaluation success within this many env steps.
ABLATION_BUDGET = 12_500


def run_label(config: dict[str, Any]) -> str:
    """A run's group in the tables: env, observation, action, algorithm, HER and what differs from the
    paper's agent (demonstrations, learner), from its config.json."""
    agent = config["agent"]
    obs = config["obs"] if len(config["obs"]) <= 12 else "the task's own"
    env = Path(config["env_id"]).name if config["env_id"].endswith(".toml") else config["env_id"]
    label = f"{env}, obs {obs}, action {config['action']}, {agent['algo'].upper()} + HER ({agent['her']['relabel']})"
    demos = agent.get("demos") or {}
    if demos.get("path") and demos.get("batch_share", 0) > 0 and demos.get("bc_weight", 0) > 0:
        label += f", {Path(demos['path']).name} (share {demos['batch_share']}, BC {demos['bc_weight']})"
    if agent.get("learner", "paper") != "paper":
        label += (
            f", learner {agent['learner']} (LayerNorm {agent['layer_norm']}, UTD {agent['utd']}, "
            f"resets {demos.get('reset_prob', 0.0)}"
            + (
                f", curriculum {demos['reset_curriculum_steps']:,}"
                if demos.get("reset_curriculum_steps")
                else ""
            )
            + ")"
        )
    return label


def grouped(run_dirs: list[Path]) -> dict[str, list[Path]]:
    """label -> its run folders, in the order labels first appear."""
    groups: dict[str, list[Path]] = {}
    for run_dir in run_dirs:
        groups.setdefault(run_label(json.loads((run_dir / "config.json").read_text())), []).append(run_dir)
    return groups


def group_table(label: str, run_dirs: list[Path], train_time: bool) -> list[str]:
    """One group's markdown table: a row per seed and a mean +- 95% CI row (over the seeds that reached
    each level; [k/n] when not all did). Seconds leave the evaluations out when `train_time`."""
    kind = "training s" if train_time else "s"
    lines = [
        f"**{label}**",
        "",
        f"| seed | env steps to 50% | to 90% | to 95% | {kind} to 50% | to 90% | to 95% | final success | env steps/s |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    per_seed = []
    for run_dir in sorted(run_dirs, key=run_seed):
        rows = read_progress_csv(run_dir)
        reached = [first_reaching(rows, t, train_time) for t in THRESHOLDS]
        last = rows[-1]
        training = last["wall_time_s"] - (0.0 if math.isnan(last["eval_time_s"]) else last["eval_time_s"])
        rate = last["env_steps"] / training if training > 0 else math.nan
        per_seed.append((reached, last["eval_success_rate"], rate))
        cells = [steps_text(s) for s, _ in reached] + [whole_text(w) for _, w in reached]
        lines.append(
            f"| {run_seed(run_dir)} | {' | '.join(cells)} | {last['eval_success_rate']:.2f} | {rate:.0f} |"
        )
    steps_cells, time_cells = [], []
    for k in range(len(THRESHOLDS)):
        steps = np.array([p[0][k][0] for p in per_seed])
        walls = np.array([p[0][k][1] for p in per_seed])
        ok = np.isfinite(steps)
        if not ok.any():
            steps_cells.append("never")
            time_cells.append("-")
            continue
        (ms, hs), (mw, hw) = mean_ci95(steps[ok]), mean_ci95(walls[ok])
        note = "" if ok.all() else f" [{ok.sum()}/{len(ok)}]"
        steps_cells.append(f"{ms:,.0f} ± {hs:,.0f}{note}")
        time_cells.append(f"{mw:.0f} ± {hw:.0f}")
    final, _ = mean_ci95(np.array([p[1] for p in per_seed]))
    rate, _ = mean_ci95(np.array([p[2] for p in per_seed]))
    lines.append(f"| mean ± 95% CI | {' | '.join(steps_cells + time_cells)} | {final:.2f} | {rate:.0f} |")
    reached_95 = sum(math.isfinite(p[0][-1][0]) for p in per_seed)
    lines += ["", f"Seeds reaching 95% within the budget: {reached_95}/{len(per_seed)}."]
    return lines


def tables(run_dirs: list[Path], train_time: bool) -> list[str]:
    """Every group's table, separated by blank lines."""
    lines: list[str] = []
    for label, dirs in grouped(run_dirs).items():
        lines += [*([""] if lines else []), *group_table(label, dirs, train_time)]
    return lines


def panda_within_twice_ur5e(run_dirs: list[Path]) -> list[str]:
    """Whether every Panda seed reached 95% within 2x the mean of the UR5e seeds' env steps to 95%."""
    steps: dict[str, list[float]] = {}
    for run_dir in run_dirs:
        env = json.loads((run_dir / "config.json").read_text())["env_id"]
        steps.setdefault(env, []).append(first_reaching(read_progress_csv(run_dir), 0.95)[0])
    ur5e, panda = np.array(steps[UR5E]), np.array(steps[PANDA])
    limit = 2 * float(np.mean(ur5e))
    ok = bool(np.all(np.isfinite(panda)) and np.all(panda <= limit))
    line = (
        f"UR5e env steps to 95%: {', '.join(steps_text(x) for x in ur5e)} (mean {np.mean(ur5e):,.0f}; twice that "
        f"{limit:,.0f}). Panda: {', '.join(steps_text(x) for x in panda)}; every Panda seed within twice the "
        f"UR5e's mean: {'yes' if ok else 'no'}."
    )
    return [line]


def every_seed_reaches(run_dirs: list[Path], threshold: float, budget: int) -> list[str]:
    """Each seed's env steps to `threshold` evaluation success and whether all got there within `budget`."""
    steps = [first_reaching(read_progress_csv(d), threshold)[0] for d in sorted(run_dirs, key=run_seed)]
    ok = all(math.isfinite(s) and s <= budget for s in steps)
    return [
        f"Env steps to {threshold:.0%}: {', '.join(steps_text(s) for s in steps)}; every seed within {budget:,}: {'yes' if ok else 'no'}."
    ]


def suite_lines(kind: str, run_dirs: list[Path]) -> list[str]:
    """A suite's tables and verdict lines: `kind` "wall" (seconds include the evaluations), "train"
    (training seconds), "panda" (wall, and the Panda-within-twice-the-UR5e verdict), "own_robot"
    (wall, and whether every seed reached OWN_ROBOT_TARGET within its budget) or "reach_target" (wall,
    and per group whether every seed reached 95 % within REACH_TARGET_STEPS)."""
    lines = tables(run_dirs, train_time=kind == "train")
    if kind == "panda":
        lines += ["", *panda_within_twice_ur5e(run_dirs)]
    if kind == "reach_target":
        for label, dirs in grouped(run_dirs).items():
            lines += ["", f"{label}: {every_seed_reaches(dirs, 0.95, REACH_TARGET_STEPS)[0]}"]
    if kind == "auc":
        lines += ["", *auc_comparison(run_dirs)]
    if kind == "own_robot":
        budget = int(json.loads((run_dirs[0] / "config.json").read_text())["total_timesteps"])
        lines += ["", *every_seed_reaches(run_dirs, OWN_ROBOT_TARGET, budget)]
    return lines


def auc_comparison(run_dirs: list[Path]) -> list[str]:
    """Per group the IQM of the seeds' AUC (normalised area under the success curve over the
    evaluations every seed has) with its 95% stratified-bootstrap interval and, for two groups of the
    fast and paper learners, fast's IQM minus paper's with its interval (tsrl.experiments.statistics,
    rliable's estimators)."""
    from tsrl.experiments import statistics as st

    lines = ["| group | seeds | AUC, IQM [95%] |", "| --- | ---: | --- |"]
    by_learner = {}
    for label, dirs in grouped(run_dirs).items():
        curves = [read_progress_csv(d) for d in dirs]
        steps = sorted(set.intersection(*({r["env_steps"] for r in c} for c in curves)))
        success = np.array(
            [[{r["env_steps"]: r["eval_success_rate"] for r in c}[s] for s in steps] for c in curves]
        )
        auc = st.area_under_curve(np.array(steps), success)
        e = st.iqm_interval(auc)
        by_learner[json.loads((dirs[0] / "config.json").read_text())["agent"].get("learner", "paper")] = auc
        lines.append(f"| {label} | {len(dirs)} | {e.point[0]:.2f} [{e.low[0]:.2f}, {e.high[0]:.2f}] |")
    if set(by_learner) == {"fast", "paper"}:
        d = st.iqm_difference(by_learner["fast"], by_learner["paper"])
        lines += ["", f"fast minus paper, AUC IQM: {d.point[0]:+.3f} [{d.low[0]:+.3f}, {d.high[0]:+.3f}]."]
    return lines


def ablation_table(variants: dict[str, list[Path]], budget: int, reference: str = "fast") -> list[str]:
    """The learner ablation (issue 27): per variant ("fast", "without-<option>") its seeds' env steps to
    95 % success, success at `budget` env steps (the target), IQM of AUC over the evaluations every run
    has, the `reference` variant's IQM minus the variant's (the option's contribution: > 0 means it
    helps) and the median training seconds to `budget` (evaluations excluded)."""
    from tsrl.experiments import statistics as st

    curves = {v: [read_progress_csv(d) for d in sorted(dirs, key=run_seed)] for v, dirs in variants.items()}
    steps, aucs = common_aucs(curves)
    lines = [
        f"| variant | seeds | env steps to 95 % | success at {budget:,} | AUC, IQM [95%] | {reference} minus variant, AUC | training s to {budget:,} (median) |",
        "| --- | ---: | --- | --- | --- | --- | ---: |",
    ]
    for v, cs in curves.items():
        at_budget = [{r["env_steps"]: r for r in c}.get(float(budget)) for c in cs]
        success = ", ".join("-" if r is None else f"{r['eval_success_rate']:.2f}" for r in at_budget)
        seconds = [r["wall_time_s"] - r["eval_time_s"] for r in at_budget if r is not None]
        reached = ", ".join(steps_text(first_reaching(c, THRESHOLDS[-1])[0]) for c in cs)
        e = st.iqm_interval(aucs[v])
        diff = "-"
        if v != reference and reference in aucs:
            d = st.iqm_difference(aucs[reference], aucs[v])
            diff = f"{d.point[0]:+.3f} [{d.low[0]:+.3f}, {d.high[0]:+.3f}]"
        median_s = f"{np.median(seconds):.0f}" if seconds else "-"
        lines.append(
            f"| {v} | {len(cs)} | {reached} | {success} | {e.point[0]:.2f} [{e.low[0]:.2f}, {e.high[0]:.2f}] "
            f"| {diff} | {median_s} |"
        )
    lines += ["", f"AUC over the evaluations at {', '.join(f'{x:,.0f}' for x in steps)} env steps."]
    return lines


# The renderers that meta.json names ("studies/learner-benchmarks/learner_tables.py:table_<kind>"), one per kind.


def saved_variants(data_dir: Path) -> dict[str, list[Path]]:
    """The run folders of a data folder laid out <variant>/<run>/, by variant."""
    variants: dict[str, list[Path]] = {}
    for run_dir in saved_runs(data_dir):
        variants.setdefault(run_dir.parent.name, []).append(run_dir)
    return variants


def table_ablation(data_dir: Path) -> list[str]:
    """`ablation_table` of a data folder laid out <variant>/<run>/ (learning.py learner-ablation)."""
    variants = saved_variants(data_dir)
    order = sorted(variants, key=lambda v: (v != "fast", v.startswith("screen-"), v))
    return ablation_table({v: variants[v] for v in order}, ABLATION_BUDGET)


def table_small(data_dir: Path) -> list[str]:
    """`ablation_table` of a learner-small data folder laid out small-<name>/<run>/, against small-final."""
    variants = saved_variants(data_dir)
    order = sorted(variants, key=lambda v: (v != "small-final", v))
    return ablation_table({v: variants[v] for v in order}, ABLATION_BUDGET, "small-final")


def table_wall(data_dir: Path) -> list[str]:
    return suite_lines("wall", saved_runs(data_dir))


def table_train(data_dir: Path) -> list[str]:
    return suite_lines("train", saved_runs(data_dir))


def table_panda(data_dir: Path) -> list[str]:
    return suite_lines("panda", saved_runs(data_dir))


def table_reach_target(data_dir: Path) -> list[str]:
    return suite_lines("reach_target", saved_runs(data_dir))


def table_auc(data_dir: Path) -> list[str]:
    return suite_lines("auc", saved_runs(data_dir))


def table_own_robot(data_dir: Path) -> list[str]:
    return suite_lines("own_robot", saved_runs(data_dir))


def speed_render(rows: list[dict[str, Any]]) -> list[str]:
    """The learner-speed table (markdown) from `speed`'s rows (or their CSV strings): per variant the
    mean over seeds of updates/s, the floor, their ratio and env steps/s with learning."""
    by_variant: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by_variant.setdefault(str(r["variant"]), []).append(r)
    lines = [
        "| variant | updates/s | floor (updates/s) | of floor | env steps/s with learning |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for label, rs in by_variant.items():
        u = float(np.mean([float(r["updates"]) / float(r["update_s"]) for r in rs]))
        f = float(np.mean([float(r["floor_updates_per_s"]) for r in rs]))
        e = float(np.mean([float(r["env_steps"]) / float(r["learn_s"]) for r in rs]))
        lines.append(
            f"| {label} | {u:.1f} | {whole_text(f)} | {'-' if not math.isfinite(u / f) else f'{u / f:.0%}'} | {e:.1f} |"
        )
    return lines


def speed_table(data_dir: Path) -> list[str]:
    """The learner-speed table from the data `speed --save` wrote (data.csv)."""
    with open(data_dir / "data.csv", newline="") as f:
        return speed_render(list(csv.DictReader(f)))
