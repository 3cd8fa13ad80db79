"""Pre-registration 34: the fast learner's evaluations under stricter acting gates, read offline from
runs already made (README.md beside this file).

The gate (tsrl.agents.acting_gate) decides only which policy acts deterministically; training is the
same under any rule, and the frozen clone evaluates to one number on a run's fixed seeds (its
evaluation at 0 env steps). So for a rule that lets the choice act only where today's does, each
evaluation is the logged one where both let the choice act and the clone's number elsewhere.

    python studies/learner-from-demos/probe_gate_rules.py RUN [RUN ...]

Per run: the clone's number, the task's floor line, and per rule the lowest evaluation after 2,500 env
steps, the final (mean of the last three evaluations) and the env steps to 95 % (sustained); and the
check that today's rule, reconstructed from the logged windows, keeps the clone exactly where the
logged evaluation is the clone's number.

Pre-registration 36 (a): the row `limit` is the gate with the clone measured on many episodes, its
window replaced by its evaluation at 0 env steps. It is not stricter than today's where the clone's
window measured above that number: where it lets the choice act and today's did not, the evaluation
is unknown (counted; lowest, final and crossing are then read on the known ones, marked `?`).
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from probe_gate import gate_scalars
from run import NEW_DEMOS, TARGETS, demo_count, floor_line, read_rows
from scipy import stats

from tsrl.agents.acting_gate import MIN_EPISODES, WINDOW
from tsrl.agents.training import read_progress
from tsrl.experiments.curves import FINAL_EVALS, sustained_crossing

Window = tuple[float, int]
"""A measured window: (success share, episodes)."""


def today(choice: Window, clone: Window) -> bool:
    """The gate as built: both windows at least MIN_EPISODES, the choice's share strictly above."""
    return min(choice[1], clone[1]) >= MIN_EPISODES and choice[0] > clone[0]


def z_rule(choice: Window, clone: Window) -> bool:
    """One-sided pooled two-proportion z of the choice's window over the clone's at least 1.645."""
    (p1, n1), (p2, n2) = choice, clone
    pooled = (p1 * n1 + p2 * n2) / (n1 + n2)
    if not today(choice, clone) or pooled in (0.0, 1.0):
        return False
    return (p1 - p2) / math.sqrt(pooled * (1 - pooled) * (1 / n1 + 1 / n2)) >= 1.645


def full_rule(choice: Window, clone: Window) -> bool:
    """Today's comparison on full windows only."""
    return choice[1] == clone[1] == WINDOW and today(choice, clone)


def bayes_rule(choice: Window, clone: Window) -> bool:
    """P(choice's success > clone's) >= 0.95 under uniform priors (numerical, on a grid)."""
    if not today(choice, clone):
        return False
    grid = np.linspace(0, 1, 2001)
    (p1, n1), (p2, n2) = choice, clone
    s1, s2 = round(p1 * n1), round(p2 * n2)
    density = stats.beta.pdf(grid, 1 + s1, 1 + n1 - s1)
    below = stats.beta.cdf(grid, 1 + s2, 1 + n2 - s2)  # P(clone's < x)
    return float(np.trapezoid(density * below, grid)) >= 0.95


RULES: dict[str, Callable[[Window, Window], bool]] = {
    "today": today,
    "z": z_rule,
    "full": full_rule,
    "bayes": bayes_rule,
}


def limit_rule(choice: Window, clone: Window, clone_number: float) -> bool:
    """Today's rule with the clone's window replaced by its evaluation `clone_number`."""
    return today(choice, (clone_number, clone[1]))


def window_size(share: float, estimate: int) -> int:
    """The episodes of a window whose share is `share`: the estimate from the episode count, or its
    neighbour where only that makes share * n a whole number (dumps lag episode ends by one)."""
    for n in (estimate, estimate - 1, estimate + 1):
        if 1 <= n <= WINDOW and abs(share * n - round(share * n)) < 1e-4:
            return n
    return max(1, min(WINDOW, estimate))


def decisions(run_dir: Path, clock: list[int], episodes: list[int]) -> list[tuple[Window, Window] | None]:
    """Per evaluation, the gate's (choice, clone) windows it acted on (None before any was logged)."""
    scalars = gate_scalars(run_dir)
    per_step: dict[str, dict[int, float]] = {}
    for tag in ("gate/choice_success", "gate/clone_success"):
        steps, values = scalars[tag]
        per_step[tag] = dict(zip(steps.astype(int).tolist(), values.tolist(), strict=True))  # later files win
    logged = sorted(per_step["gate/choice_success"])
    out: list[tuple[Window, Window] | None] = []
    for step in clock:
        at = [s for s in logged if s <= step]
        if not at:
            out.append(None)
            continue
        s = at[-1]
        ended = round(float(np.interp(s, clock, episodes)))  # gate episodes (no demonstration starts)
        choice_share = per_step["gate/choice_success"][s]
        clone_share = per_step["gate/clone_success"][s]
        if math.isnan(choice_share) or math.isnan(clone_share):
            out.append(None)
            continue
        choice_n = window_size(choice_share, min(WINDOW, (ended + 2) // 4))
        clone_n = window_size(clone_share, min(WINDOW, ended // 4))
        out.append(((choice_share, choice_n), (clone_share, clone_n)))
    return out


def read_run(run_dir: Path) -> None:
    cfg = json.loads((run_dir / "config.json").read_text())
    arm, task = run_dir.parent.parent.name, run_dir.parent.name
    if (cfg["agent"].get("demos") or {}).get("reset_prob"):
        print(f"\n{arm} {task} seed {cfg['seed']}: skipped (demonstration starts: gate episodes unknown)")
        return
    rows = read_progress(run_dir)
    clock = [int(r["env_steps"]) for r in rows]
    episodes = [int(r["episodes"]) for r in rows]
    success = [float(r["eval_success_rate"]) for r in rows]
    clone = success[0]
    windows = decisions(run_dir, clock, episodes)
    n = demo_count(arm)
    line, target = floor_line(read_rows(), task, n, NEW_DEMOS.get(task, "")), TARGETS.get((task, n))
    mismatches = sum(
        1
        for w, s, c in zip(windows, success, clock, strict=True)
        if c > 0 and (w is None or not today(*w)) and abs(s - clone) > 1e-9
    )
    print(
        f"\n{arm} {task} seed {cfg['seed']} (to {clock[-1]:,}): clone {clone:.2f}, line {line:.3f}, "
        f"target {target or '-'}; today's clone evaluations unlike the clone's number: {mismatches}"
    )
    print(
        "\n| rule | choice acts at (of evaluations) | lowest after 2,500 | below the line | final | 95 % from |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    logged = [w is not None and today(*w) for w in windows]
    for name, rule in RULES.items():
        acts = [w is not None and rule(*w) for w in windows]
        print_row(name, acts, [False] * len(acts), clock, success, clone, line)
    acts = [w is not None and limit_rule(*w, clone) for w in windows]
    unknown = [a and not t for a, t in zip(acts, logged, strict=True)]
    print_row("limit", acts, unknown, clock, success, clone, line)


def print_row(
    name: str,
    acts: list[bool],
    unknown: list[bool],
    clock: list[int],
    success: list[float],
    clone: float,
    line: float,
) -> None:
    """One rule's table row: evaluations where it acts are the logged ones, else the clone's number;
    `unknown` ones (the rule acts where the logged run's gate did not) are left out and counted."""
    curve = [s if a else clone for s, a in zip(success, acts, strict=True)]
    known = [(c, s) for c, s, u in zip(clock, curve, unknown, strict=True) if not u]
    after = [s for c, s in known if c >= 2_500]
    crossing = sustained_crossing([c for c, _ in known], [s for _, s in known], 0.95)
    mark = "?" if any(unknown[-FINAL_EVALS:]) else ""
    final = np.mean(
        [s for s, u in zip(curve[-FINAL_EVALS:], unknown[-FINAL_EVALS:], strict=True) if not u] or [np.nan]
    )
    unknown_note = f" ({sum(unknown)} unknown)" if any(unknown) else ""
    print(
        f"| {name} | {sum(acts)} of {len(acts)}{unknown_note} | {min(after, default=math.nan):.2f} | {sum(s < line for s in after)} | "
        f"{final:.3f}{mark} | {'-' if math.isnan(crossing) else f'{crossing:,.0f}'}{'?' if any(unknown) else ''} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+")
    for run_dir in parser.parse_args().runs:
        read_run(run_dir)


if __name__ == "__main__":
    main()
