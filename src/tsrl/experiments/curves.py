"""A configuration's learning curve across seeds (`Curve`): each seed's evaluation success at the
evaluations every seed reached, and the per-seed metrics the report compares (AUC, final success,
final penalised share); `curves` builds them from tidy result rows (tsrl.experiments.aggregate)."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import statistics as st
from .config import Key

#: Evaluations at the end of a curve whose mean is a seed's final success (and penalised share).
FINAL_EVALS = 3


def sustained_crossing(
    clock: list[float], success: list[float], level: float, window: int = FINAL_EVALS
) -> float:
    """The clock (env steps) of the first evaluation from which the mean of `window` consecutive
    evaluations stays at or above `level`: the windows starting there and at every later evaluation
    (as far as the run goes) all have it; NaN if there is none. One noisy evaluation at the level
    does not count, nor a run that reaches it and falls back."""
    means = [float(np.mean(success[i : i + window])) for i in range(len(success) - window + 1)]
    first = math.nan
    for i in reversed(range(len(means))):
        if means[i] < level:
            break
        first = float(clock[i])
    return first


def row_key(row: dict[str, Any]) -> Key:
    """The configuration (env, obs, action, algo, variant) of a tidy result row."""
    return (row["env"], row["obs"], row["action"], row["algo"], row["variant"])


@dataclass(frozen=True)
class Curve:
    """A configuration's learning curve: success of each seed at the evaluations all seeds reached."""

    key: Key
    seeds: tuple[int, ...]
    eval_episodes: tuple[int, ...]
    """Episodes per evaluation of the configuration's runs (distinct values)."""
    env_steps: np.ndarray
    """(m,) evaluation env steps common to all seeds."""
    success: np.ndarray
    """(n seeds, m) evaluation success rates."""
    penalised: np.ndarray | None = None
    """(n seeds, m) shares of evaluation episodes with a penalised step (NaN where not recorded)."""

    def stats(self) -> st.Estimate:
        """IQM across seeds and its 95% stratified-bootstrap interval at each evaluation."""
        return st.iqm_interval(self.success)

    def seed_metrics(self) -> dict[str, np.ndarray]:
        """Per seed (n,): each of COMPARISON_METRICS (NaN AUC with a single evaluation)."""
        auc = (
            st.area_under_curve(self.env_steps, self.success)
            if len(self.env_steps) > 1
            else np.full(len(self.seeds), math.nan)
        )
        penalised = self.penalised if self.penalised is not None else np.full(self.success.shape, math.nan)
        return {
            "auc": auc,
            "final_success": self.success[:, -FINAL_EVALS:].mean(axis=1),
            "final_penalised": penalised[:, -FINAL_EVALS:].mean(axis=1),
        }


def curves(rows: list[dict[str, Any]]) -> list[Curve]:
    """One Curve per configuration, in the order configurations first appear in `rows`."""
    by_run: dict[Key, dict[int, dict[int, dict[str, Any]]]] = defaultdict(lambda: defaultdict(dict))
    for r in rows:
        by_run[row_key(r)][r["seed"]][r["env_steps"]] = r
    out = []
    for key, runs in by_run.items():
        seeds = tuple(sorted(runs))
        common = sorted(set.intersection(*(set(runs[s]) for s in seeds)))
        out.append(
            Curve(
                key=key,
                seeds=seeds,
                eval_episodes=tuple(sorted({r["eval_episodes"] for s in seeds for r in runs[s].values()})),
                env_steps=np.array(common, dtype=int),
                success=np.array([[runs[s][t]["eval_success_rate"] for t in common] for s in seeds]),
                penalised=np.array(
                    [[runs[s][t].get("eval_penalised_rate", math.nan) for t in common] for s in seeds],
                    dtype=float,
                ),
            )
        )
    return out
