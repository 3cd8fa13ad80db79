"""Aggregates an experiment's run folders: tidy results, per-configuration statistics, the report.

A configuration is (env, obs, action, algo); its runs differ by seed. Statistics across seeds use a
seeded percentile bootstrap of the mean (BOOTSTRAP_RESAMPLES resamples of the seeds with
replacement; the interval holds the middle 95% of the resampled means):

- learning curves: mean success rate and its 95% interval at each evaluation that every seed of the
  configuration has reached (a seed still running shortens its configuration's curve);
- final success: per seed, the mean of the last FINAL_EVALS of those common evaluations;
- episodes / env steps to a threshold (50%, 90%): per seed, the first evaluation whose success rate is
  at or above it. A seed that never reaches it within its budget is *not* given a value: the summary
  reports how many seeds reached it (k of n) and the mean and interval over those k only, which is
  optimistic when k < n; docs/experiments.md says more.
"""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..agents.config import TrainConfig
from ..agents.run_folder import CONFIG_FILE, load_config, read_progress
from ..exceptions import InvalidConfig, TsrlError
from .config import EXPERIMENT_FILE, Key, config_labels
from .plots import plot_curves
from .runner import ERROR_FILE

RESULT_COLUMNS: tuple[str, ...] = (
    "env",
    "obs",
    "action",
    "algo",
    "variant",
    "seed",
    "env_steps",
    "episodes",
    "wall_time_s",
    "eval_success_rate",
)
THRESHOLDS: tuple[float, ...] = (0.5, 0.9)
FINAL_EVALS = 3
BOOTSTRAP_RESAMPLES = 10_000
BOOTSTRAP_SEED = 0
RESULTS_CSV = "results.csv"
SUMMARY_CSV = "summary.csv"
SUMMARY_MD = "summary.md"
CURVES_EPISODES = "learning_curves_episodes.png"
CURVES_STEPS = "learning_curves_steps.png"


def find_runs(results_dir: Path) -> list[Path]:
    """Run folders (holding config.json) directly inside `results_dir`, sorted by name."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise InvalidConfig(f"results folder {results_dir} does not exist")
    runs = sorted(p for p in results_dir.iterdir() if (p / CONFIG_FILE).is_file())
    if not runs:
        raise InvalidConfig(
            f"no run folders in {results_dir} (a run folder holds {CONFIG_FILE}); pass an experiment's "
            "results folder, e.g. results/quick-reach"
        )
    return runs


#: Config fields that are grid axes, or that do not change what a run learns: not part of a variant.
_NOT_VARIANT = {
    "env_id",
    "obs",
    "action",
    "agent.algo",
    "seed",
    "total_timesteps",
    "checkpoint_freq",
    "torch_threads",
}


def variants(cfgs: list[TrainConfig]) -> list[str]:
    """Per config, the settings (beyond env, obs, action, algo, seed) that differ among `cfgs`, as
    `field=value, ...`; empty when all share them (as the runs of one experiment do)."""
    flat = [{k: v for k, v in _flatten(c.to_dict()).items() if k not in _NOT_VARIANT} for c in cfgs]
    fields = sorted({k for f in flat for k in f if len({repr(g.get(k)) for g in flat}) > 1})
    return [", ".join(f"{k}={f.get(k)}" for k in fields) for f in flat]


def row_key(row: dict[str, Any]) -> Key:
    return (row["env"], row["obs"], row["action"], row["algo"], row["variant"])


def collect(run_dirs: list[Path]) -> list[dict[str, Any]]:
    """Tidy rows, one per run and evaluation, with RESULT_COLUMNS."""
    cfgs = [load_config(d) for d in run_dirs]
    rows = []
    seen: dict[tuple[Key, int], Path] = {}
    for run_dir, cfg, variant in zip(run_dirs, cfgs, variants(cfgs), strict=True):
        key = (cfg.env_id, cfg.obs, cfg.action, cfg.agent.algo, variant)
        if (key, cfg.seed) in seen:
            raise InvalidConfig(
                f"{seen[key, cfg.seed].name} and {run_dir.name} are the same configuration and seed; "
                "report one experiment's folder at a time"
            )
        seen[key, cfg.seed] = run_dir
        for r in read_progress(run_dir):
            rows.append(
                {
                    "env": cfg.env_id,
                    "obs": cfg.obs,
                    "action": cfg.action,
                    "algo": cfg.agent.algo,
                    "variant": variant,
                    "seed": cfg.seed,
                    "env_steps": int(r["env_steps"]),
                    "episodes": int(r["episodes"]),
                    "wall_time_s": r["wall_time_s"],
                    "eval_success_rate": r["eval_success_rate"],
                }
            )
    return rows


def bootstrap_mean_ci(
    values: np.ndarray, resamples: int = BOOTSTRAP_RESAMPLES, seed: int = BOOTSTRAP_SEED
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean over axis 0 (seeds) and its 95% percentile-bootstrap interval, for every column.

    values (n,) or (n, m) -> mean, low, high of shape () or (m,). Seeded: the same data give the same
    interval. With one seed the interval is that value (no spread can be estimated).
    """
    values = np.asarray(values, dtype=float)
    n = values.shape[0]
    mean = values.mean(axis=0)
    if n < 2:
        return mean, mean.copy(), mean.copy()
    idx = np.random.default_rng(seed).integers(0, n, size=(resamples, n))
    means = values[idx].mean(axis=1)
    low, high = np.percentile(means, [2.5, 97.5], axis=0)
    return mean, low, high


@dataclass(frozen=True)
class Curve:
    """A configuration's learning curve: success of each seed at the evaluations all seeds reached."""

    key: Key
    seeds: tuple[int, ...]
    env_steps: np.ndarray
    """(m,) evaluation env steps common to all seeds."""
    episodes: np.ndarray
    """(m,) mean training episodes at those evaluations (the same for every seed with fixed-length
    episodes)."""
    success: np.ndarray
    """(n seeds, m) evaluation success rates."""

    def stats(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mean and 95% bootstrap interval across seeds at each evaluation."""
        return bootstrap_mean_ci(self.success)


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
                env_steps=np.array(common, dtype=int),
                episodes=np.array([np.mean([runs[s][t]["episodes"] for s in seeds]) for t in common]),
                success=np.array([[runs[s][t]["eval_success_rate"] for t in common] for s in seeds]),
            )
        )
    return out


def first_reaching(rows: list[dict[str, Any]], threshold: float) -> dict[str, float] | None:
    """The first evaluation of one run (rows sorted by env steps) at or above `threshold`, or None."""
    for r in rows:
        if r["eval_success_rate"] >= threshold:
            return {"episodes": r["episodes"], "env_steps": r["env_steps"]}
    return None


def summarize(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One summary row per configuration (see the module docstring for each statistic)."""
    per_run: dict[tuple[Key, int], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        per_run[row_key(r), r["seed"]].append(r)
    summary = []
    for curve in curves(rows):
        env, obs, action, algo, variant = curve.key
        runs = [sorted(per_run[curve.key, s], key=lambda r: r["env_steps"]) for s in curve.seeds]
        last = curve.success[:, -FINAL_EVALS:]
        final, final_lo, final_hi = bootstrap_mean_ci(last.mean(axis=1))
        row: dict[str, Any] = {
            "env": env,
            "obs": obs,
            "action": action,
            "algo": algo,
            "variant": variant,
            "seeds": len(curve.seeds),
            "final_env_steps": int(curve.env_steps[-1]),
            "final_evals": last.shape[1],
            "final_success_mean": float(final),
            "final_success_ci_low": float(final_lo),
            "final_success_ci_high": float(final_hi),
        }
        for threshold in THRESHOLDS:
            pct = round(threshold * 100)
            hits = [h for h in (first_reaching(run, threshold) for run in runs) if h is not None]
            row[f"seeds_reaching_{pct}"] = len(hits)
            for unit in ("episodes", "env_steps"):
                values = np.array([h[unit] for h in hits], dtype=float)
                mean, lo, hi = bootstrap_mean_ci(values) if len(values) else (math.nan,) * 3
                row[f"{unit}_to_{pct}_mean"] = float(mean)
                row[f"{unit}_to_{pct}_ci_low"] = float(lo)
                row[f"{unit}_to_{pct}_ci_high"] = float(hi)
        row["wall_time_s_mean"] = float(np.mean([run[-1]["wall_time_s"] for run in runs]))
        summary.append(row)
    return summary


def write_csv(path: Path, rows: list[dict[str, Any]], columns: list[str] | tuple[str, ...]) -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(columns))
        writer.writeheader()
        for r in rows:
            writer.writerow({k: _cell(v) for k, v in r.items()})
    return path


def write_report(results_dir: Path | str) -> list[Path]:
    """Writes results.csv, summary.csv, summary.md and the two learning-curve PNGs into
    `results_dir`; returns their paths."""
    results_dir = Path(results_dir)
    run_dirs = find_runs(results_dir)
    try:
        rows = collect(run_dirs)
    except TsrlError as err:  # a config.json that does not load
        raise InvalidConfig(str(err)) from None
    if not rows:
        raise InvalidConfig(f"no evaluations yet in the runs of {results_dir}")
    rows.sort(key=lambda r: (*row_key(r), r["seed"], r["env_steps"]))
    summary = summarize(rows)
    all_curves = curves(rows)
    title = _experiment_name(results_dir)
    paths = [
        write_csv(results_dir / RESULTS_CSV, rows, RESULT_COLUMNS),
        write_csv(results_dir / SUMMARY_CSV, summary, list(summary[0])),
        plot_curves(all_curves, "episodes", results_dir / CURVES_EPISODES, title),
        plot_curves(all_curves, "env_steps", results_dir / CURVES_STEPS, title),
    ]
    failed = [d.name for d in run_dirs if (d / ERROR_FILE).is_file()]
    empty = [d.name for d in run_dirs if not read_progress(d)]
    (results_dir / SUMMARY_MD).write_text(markdown_summary(results_dir, summary, failed, empty))
    paths.insert(2, results_dir / SUMMARY_MD)
    return paths


_HOW_TO_READ = (
    "Mean across seeds [95% percentile-bootstrap interval: {resamples:,} resamples of the seeds, "
    "numpy seed {seed}]. **Final success**: per seed, the mean eval success rate of the last {final} "
    "evaluations that every seed of the configuration reached, the last of them at *at env steps* (a seed "
    "still running holds its configuration back). **Episodes / env steps to 50% and 90%**: per seed, the "
    "first evaluation at or above the threshold. `k/n`: k of the n seeds reached it within their budget; "
    "the mean and interval are over those k only: seeds that never reached it are left out, not counted "
    "at the budget, so when k < n the mean is optimistic (— when none did). With one seed, or one "
    "reaching seed, the interval is that value. Wall time: training plus evaluations, per run."
)


def markdown_summary(
    results_dir: Path, summary: list[dict[str, Any]], failed: list[str], empty: list[str]
) -> str:
    """summary.md: the learning curves, the table, and how to read it."""
    description = _experiment_info(results_dir).get("description", "")
    header = ["configuration", "seeds", "final success", "at env steps"]
    header += [f"{u} to {round(t * 100)}%" for t in THRESHOLDS for u in ("episodes", "env steps")]
    header += ["wall time [s]"]
    lines = [f"# {_experiment_name(results_dir)}", ""] + ([description, ""] if description else [])
    lines += [
        f"![success rate vs episodes]({CURVES_EPISODES})",
        "",
        f"![success rate vs env steps]({CURVES_STEPS})",
    ]
    lines += ["", "| " + " | ".join(header) + " |", "| --- | ---: | --- | ---: |" + " --- |" * 4 + " ---: |"]
    for r, label in zip(summary, config_labels([row_key(r) for r in summary]), strict=True):
        cells = [label, str(r["seeds"]), _interval(r, "final_success", ".2f"), str(r["final_env_steps"])]
        for pct in (round(t * 100) for t in THRESHOLDS):
            reached = f"{r[f'seeds_reaching_{pct}']}/{r['seeds']}: "
            cells += [reached + _interval(r, f"{unit}_to_{pct}", ".0f") for unit in ("episodes", "env_steps")]
        cells.append(f"{r['wall_time_s_mean']:.0f}")
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        _HOW_TO_READ.format(resamples=BOOTSTRAP_RESAMPLES, seed=BOOTSTRAP_SEED, final=FINAL_EVALS),
        "",
    ]
    if failed:
        lines += [f"Failed runs (error.txt in their folders): {', '.join(failed)}.", ""]
    if empty:
        lines += [f"Runs without evaluations (left out): {', '.join(empty)}.", ""]
    lines.append(
        f"Data: [{RESULTS_CSV}]({RESULTS_CSV}) (one row per run and evaluation), [{SUMMARY_CSV}]({SUMMARY_CSV}). "
        f"Regenerate with `tsrl report {results_dir}`.\n"
    )
    return "\n".join(lines)


def _interval(row: dict[str, Any], stat: str, fmt: str) -> str:
    mean, lo, hi = row[f"{stat}_mean"], row[f"{stat}_ci_low"], row[f"{stat}_ci_high"]
    if math.isnan(mean):
        return "—"
    return f"{mean:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]"


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return value


def _experiment_info(results_dir: Path) -> dict[str, Any]:
    path = results_dir / EXPERIMENT_FILE
    try:
        return json.loads(path.read_text()) if path.is_file() else {}
    except json.JSONDecodeError:
        return {}


def _experiment_name(results_dir: Path) -> str:
    return _experiment_info(results_dir).get("name") or results_dir.resolve().name


def _flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out |= _flatten(v, f"{prefix}{k}.")
        else:
            out[prefix + k] = v
    return out
