"""Aggregates an experiment's run folders: tidy results, per-configuration statistics, the pre-registered
comparisons, the report. Statistics across seeds come from tsrl.experiments.statistics (rliable):

- learning curves: the interquartile mean (IQM) of the seeds' success rates and its 95%
  stratified-bootstrap interval at each evaluation that every seed of the configuration has reached (a
  seed still running shortens its configuration's curve);
- AUC (sample efficiency, the primary metric): per seed, the area under its success curve over those
  evaluations, normalised by their span of env steps to [0, 1]; then IQM and interval across seeds;
- final success: per seed, the mean of the last FINAL_EVALS of those evaluations; IQM and interval;
- final penalised episodes (tasks with penalties, e.g. touching an obstacle): per seed, the mean share
  of evaluation episodes with a penalised step over the last FINAL_EVALS evaluations; IQM and interval;
- env steps / episodes to a threshold (50%, 90%, 95%): per seed, the first evaluation from which the
  mean of FINAL_EVALS consecutive evaluations stays at or above it (curves.sustained_crossing: one
  noisy evaluation does not count); a seed that never gets there is censored at its last evaluation, and the Kaplan-Meier median is reported
  with the number of seeds that reached it (k of n); inf when fewer than half are known to have;
- comparisons (the experiment file's [[comparisons]]): IQM(a) - IQM(b) of a per-seed metric with its
  interval, the probability of improvement P(a > b) with its interval, a Mann-Whitney U test on the
  registered side, Holm's correction over the experiment's comparisons, the minimum detectable effect
  and a verdict (statistics.verdict).
"""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from pathlib import Path
from typing import Any, cast

import numpy as np

from ..agents.run_folder import CONFIG_FILE, check_progress, load_config, read_progress
from ..configs import load_table
from ..envs import OBS_PRESETS
from ..exceptions import InvalidConfig, TsrlError
from . import evaluations as ev
from . import statistics as st
from .config import EVAL_METRIC, EXPERIMENT_FILE, Comparison, Key, config_labels, env_label
from .curves import FINAL_EVALS, Curve, curves, row_key, sustained_crossing
from .plots import describe_agent, plot_curves, plot_penalised, plot_profile
from .results import find_runs, variants
from .runner import ERROR_FILE
from .statistics import THRESHOLDS

RESULT_COLUMNS: tuple[str, ...] = (
    "env",
    "obs",
    "action",
    "algo",
    "variant",
    "seed",
    "eval_episodes",
    "env_steps",
    "episodes",
    "wall_time_s",
    "eval_success_rate",
    "eval_penalised_rate",
)
RESULTS_CSV = "results.csv"
SUMMARY_CSV = "summary.csv"
COMPARISONS_CSV = "comparisons.csv"
SUMMARY_MD = "summary.md"
CURVES_PNG = "learning_curves.png"
PROFILE_PNG = "performance_profile.png"
PENALISED_PNG = "penalised_curves.png"
#: Thresholds of the AUC performance profile.
PROFILE_TAUS = np.linspace(0.0, 1.0, 51)


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
        check_progress(run_dir)
        for r in read_progress(run_dir):
            rows.append(
                {
                    "env": env_label(cfg.env_id),
                    "obs": cfg.obs,
                    "action": cfg.action,
                    "algo": cfg.agent.algo,
                    "variant": variant,
                    "seed": cfg.seed,
                    "eval_episodes": cfg.eval_episodes,
                    "env_steps": int(r["env_steps"]),
                    "episodes": int(r["episodes"]),
                    "wall_time_s": r["wall_time_s"],
                    "eval_success_rate": r["eval_success_rate"],
                    "eval_penalised_rate": r.get("eval_penalised_rate", math.nan),
                }
            )
    return rows


#: Columns of results.csv that are integers; the others past the configuration's are floats.
_INT_COLUMNS = ("seed", "eval_episodes", "env_steps", "episodes")


def read_results(path: Path) -> list[dict[str, Any]]:
    """Tidy rows from a results.csv that `tsrl report` wrote (a committed study's data without its run
    folders): RESULT_COLUMNS typed as `collect` makes them; a column an older report lacks is NaN
    (eval_episodes: 0)."""
    with open(path, newline="") as f:
        raw = list(csv.DictReader(f))
    rows = []
    for r in raw:
        row: dict[str, Any] = {k: r.get(k, "") for k in ("env", "obs", "action", "algo", "variant")}
        for k in RESULT_COLUMNS[5:]:
            value = r.get(k, "")
            if k in _INT_COLUMNS:
                row[k] = int(value) if value else 0
            else:
                row[k] = float(value) if value else math.nan
        rows.append(row)
    return rows


def sort_key(row: dict[str, Any]) -> tuple[Any, ...]:
    """Orders rows by configuration, observation presets in the paper's Table I order, then seed and
    env steps."""
    presets = list(OBS_PRESETS)
    rank = presets.index(row["obs"]) if row["obs"] in presets else len(presets)
    return (row["env"], rank, *row_key(row)[1:], row["seed"], row["env_steps"])


def time_to_threshold(run: list[dict[str, Any]], threshold: float, unit: str) -> tuple[float, bool]:
    """(time, reached) of one run (rows sorted by env steps) in `unit` (env_steps or episodes): the
    evaluation from which the mean of FINAL_EVALS consecutive evaluations stays at or above
    `threshold` (sustained_crossing), or its last evaluation, censored, if there is none."""
    time = sustained_crossing([float(r[unit]) for r in run], [r["eval_success_rate"] for r in run], threshold)
    return (time, True) if not math.isnan(time) else (float(run[-1][unit]), False)


def summarize(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One summary row per configuration (see the module docstring for each statistic)."""
    per_run: dict[tuple[Key, int], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        per_run[row_key(r), r["seed"]].append(r)
    summary = []
    for curve in curves(rows):
        env, obs, action, algo, variant = curve.key
        runs = [sorted(per_run[curve.key, s], key=lambda r: r["env_steps"]) for s in curve.seeds]
        row: dict[str, Any] = {
            "env": env,
            "obs": obs,
            "action": action,
            "algo": algo,
            "variant": variant,
            "seeds": len(curve.seeds),
            "eval_episodes": "/".join(map(str, curve.eval_episodes)),
            "evaluations": len(curve.env_steps),
            "final_env_steps": int(curve.env_steps[-1]),
            "final_evals": min(FINAL_EVALS, len(curve.env_steps)),
        }
        for metric, values in curve.seed_metrics().items():
            est = st.iqm_interval(values) if not np.isnan(values).any() else None
            for part in ("point", "low", "high"):
                column = f"{metric}_{'iqm' if part == 'point' else f'ci_{part}'}"
                row[column] = float(getattr(est, part)[0]) if est else math.nan
        for threshold in THRESHOLDS:
            pct = round(threshold * 100)
            for unit in ("env_steps", "episodes"):
                times, reached = zip(*(time_to_threshold(run, threshold, unit) for run in runs), strict=True)
                row[f"{unit}_to_{pct}_km_median"] = st.km_median(np.array(times), np.array(reached))
            row[f"seeds_reaching_{pct}"] = sum(reached)
        row["wall_time_s_mean"] = float(np.mean([run[-1]["wall_time_s"] for run in runs]))
        summary.append(row)
    return summary


def compare(
    all_curves: list[Curve],
    comparisons: tuple[Comparison, ...],
    eval_success: dict[str, np.ndarray] | None = None,
) -> list[dict[str, Any]]:
    """One row per comparison whose two arms are both in `all_curves` (labelled by config_labels), or
    for metric "success" both in `eval_success` (evaluation-only arms: per-seed success rates), with
    a value for every seed (AUC needs two evaluations):
    effect IQM(a) - IQM(b) and P(a > b) with intervals, Mann-Whitney p on the registered side, Holm's
    adjustment over all of `comparisons`, minimum detectable effect and verdict."""
    by_label = dict(zip(config_labels([c.key for c in all_curves]), all_curves, strict=True))
    metrics = {label: curve.seed_metrics() for label, curve in by_label.items()}
    metrics |= {label: {EVAL_METRIC: values} for label, values in (eval_success or {}).items()}
    present = [
        c
        for c in comparisons
        if all(
            c.metric in metrics.get(arm, {}) and not np.isnan(metrics[arm][c.metric]).any()
            for arm in (c.a, c.b)
        )
    ]
    out: list[dict[str, Any]] = []
    effects: list[st.Estimate] = []
    for c in present:
        direction = cast(st.Direction, c.direction)  # Comparison checks it is one of DIRECTIONS
        x, y = metrics[c.a][c.metric], metrics[c.b][c.metric]
        bounds = {arm: st.iqm_interval(v) for arm, v in ((c.a, x), (c.b, y))}  # every metric is a rate
        flags = [f"{arm}: {f}" for arm, e in bounds.items() if (f := st.bound_flags(e.low[0], e.high[0]))]
        effect = st.iqm_difference(x, y)
        poi = st.probability_of_improvement(x, y)
        effects.append(effect)
        out.append(
            {
                "a": c.a,
                "b": c.b,
                "metric": c.metric,
                "direction": c.direction,
                "seeds_a": len(x),
                "seeds_b": len(y),
                "effect": float(effect.point[0]),
                "effect_ci_low": float(effect.low[0]),
                "effect_ci_high": float(effect.high[0]),
                "effect_sd": float(effect.sd[0]),
                "poi": float(poi.point[0]),
                "poi_ci_low": float(poi.low[0]),
                "poi_ci_high": float(poi.high[0]),
                "p": st.mann_whitney_p(x, y, direction),
                "p_method": st.mann_whitney_method(x, y),
                "mde": st.minimum_detectable_effect(float(effect.sd[0]), len(comparisons), direction),
                "min_effect": math.nan if c.min_effect is None else c.min_effect,
                "flags": "; ".join(flags),
            }
        )
    # The family is every pre-registered comparison: one not computed yet counts as p = 1.
    family = st.holm([r["p"] for r in out] + [1.0] * (len(comparisons) - len(out)))
    for row, c, effect, p_holm in zip(out, present, effects, family, strict=False):
        row["p_holm"] = float(p_holm)
        row["verdict"] = st.verdict(
            c.a, c.b, effect, row["p_holm"], row["mde"], cast(st.Direction, c.direction), c.min_effect
        )
    return out


def write_csv(path: Path, rows: list[dict[str, Any]], columns: list[str] | tuple[str, ...]) -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(columns))
        writer.writeheader()
        for r in rows:
            writer.writerow({k: _cell(v) for k, v in r.items()})
    return path


def write_report(results_dir: Path | str) -> list[Path]:
    """Writes results.csv, summary.csv, comparisons.csv (when the experiment registers comparisons),
    summary.md, the learning curves and the AUC performance profile into `results_dir`; returns their
    paths. A folder with results.csv and no run folders (a committed study) is re-rendered from it."""
    results_dir = Path(results_dir)
    committed = (
        results_dir.is_dir()
        and not any((p / CONFIG_FILE).is_file() for p in results_dir.iterdir())
        and (results_dir / RESULTS_CSV).is_file()
    )
    run_dirs = [] if committed else find_runs(results_dir)
    try:  # a committed study (results.csv, no run folders) is re-rendered from its data
        rows = read_results(results_dir / RESULTS_CSV) if committed else collect(run_dirs)
    except TsrlError as err:  # a config.json that does not load
        raise InvalidConfig(str(err)) from None
    if not rows:
        raise InvalidConfig(f"no evaluations yet in the runs of {results_dir}")
    rows.sort(key=sort_key)
    summary = summarize(rows)
    all_curves = curves(rows)
    info = _experiment_info(results_dir)
    comparisons = tuple(
        load_table(Comparison, c, source=results_dir / EXPERIMENT_FILE, where=f"comparisons[{i}]")
        for i, c in enumerate(info.get("comparisons", []))
    )
    eval_rows = ev.read_evaluations(results_dir / ev.EVALUATIONS_CSV)
    order = [label for e in info.get("evaluate", []) for label in _eval_labels(e)]
    eval_summary = ev.summarize_evaluations(eval_rows, order or None)
    compared = compare(all_curves, comparisons, ev.per_seed_success(eval_rows))
    name = _experiment_name(results_dir)
    paths = [
        write_csv(results_dir / RESULTS_CSV, rows, RESULT_COLUMNS),
        write_csv(results_dir / SUMMARY_CSV, summary, list(summary[0])),
    ]
    if eval_summary:
        paths.append(write_csv(results_dir / ev.EVAL_SUMMARY_CSV, eval_summary, list(eval_summary[0])))
        paths += ev.plot_profiles(eval_summary, eval_rows, lambda key: results_dir / f"robustness__{key}.png")
    if compared:
        paths.append(write_csv(results_dir / COMPARISONS_CSV, compared, list(compared[0])))
    failed = [d.name for d in run_dirs if (d / ERROR_FILE).is_file()]
    empty = [d.name for d in run_dirs if not read_progress(d)]
    (results_dir / SUMMARY_MD).write_text(
        markdown_summary(results_dir, summary, compared, len(comparisons), failed, empty, eval_summary)
    )
    paths.append(results_dir / SUMMARY_MD)
    agent = describe_agent(info)
    paths.append(plot_curves(all_curves, results_dir / CURVES_PNG, name, agent))
    if _has_penalties(all_curves):
        paths.append(plot_penalised(all_curves, results_dir / PENALISED_PNG, name, agent))
    labels = config_labels([c.key for c in all_curves])
    aucs = {label: c.seed_metrics()["auc"] for label, c in zip(labels, all_curves, strict=True)}
    if all(not np.isnan(v).any() for v in aucs.values()):
        profile = st.performance_profile(aucs, PROFILE_TAUS)
        paths.append(plot_profile(profile, PROFILE_TAUS, all_curves, results_dir / PROFILE_PNG, name, agent))
    return paths


def plot_runs(run_dirs: list[Path], out: Path) -> Path:
    """`tsrl plot`: the learning curves of any run folders, grouped into configurations, with the
    report's statistics (IQM and stratified-bootstrap interval)."""
    rows = sorted(collect([Path(d) for d in run_dirs]), key=sort_key)
    if not rows:
        raise InvalidConfig(f"no evaluations yet in {', '.join(map(str, run_dirs))}")
    return plot_curves(curves(rows), out)


_HOW_TO_READ = (
    "IQM: interquartile mean across seeds (the mean of the middle half; rliable). [95% interval]: "
    "percentile interval of rliable's stratified bootstrap, {resamples:,} resamples of the seeds, numpy "
    "seed {seed}. **AUC** (the primary sample-efficiency metric): per seed, the area under its success "
    "curve over the evaluations every seed of the configuration reached, divided by their span of env "
    "steps (1 = success 1 at every evaluation). **Final success**: per seed, the mean of the last "
    "{final} of those evaluations. **Env steps to {thresholds}**: Kaplan-Meier median of each seed's first "
    "evaluation at or above the threshold; a seed that never got there counts as censored at its last "
    "evaluation, not dropped; `k/n` seeds reached it; `> N` when fewer than half are known to have "
    "(the median lies beyond the N env steps evaluated). Wall time: training plus evaluations, per run."
)
_HOW_TO_READ_COMPARISONS = (
    "**Comparisons** (pre-registered in the experiment file): effect = IQM(a) - IQM(b) of the per-seed "
    "metric, with its 95% interval (each arm's seeds resampled on their own); P(a > b): probability "
    "that a random seed of a beats one of b (ties count half), with its interval; p: Mann-Whitney U test "
    "on the per-seed metric, one-sided in the registered direction (two-sided when none); p method: "
    "SciPy's exact distribution when no two seeds tie, else the normal approximation with tie "
    "correction; p (Holm): adjusted over the experiment's {m} comparison(s). A difference is *detected* "
    "when p (Holm) < {alpha}, *detected, smaller than the relevant effect* when the whole 95% interval "
    "also lies below the registered min_effect. Flags: an arm whose 95% interval of the metric comes "
    "within {margin} of 0 (floor) or 1 (ceiling): a difference there is capped by the bound, not evidence "
    "of none. MDE: the smallest effect this study detects with {power:.0%} power at level "
    "{alpha} / {m} (normal approximation with the effect's bootstrap standard deviation); a "
    "non-detection says nothing about effects smaller than it."
)


def markdown_summary(
    results_dir: Path,
    summary: list[dict[str, Any]],
    compared: list[dict[str, Any]],
    registered: int,
    failed: list[str],
    empty: list[str],
    eval_summary: list[dict[str, Any]] | None = None,
) -> str:
    """summary.md: the learning curves, the table, the evaluation-only arms, the comparisons, and how
    to read them."""
    description = _experiment_info(results_dir).get("description", "")
    lines = [f"# {_experiment_name(results_dir)}", ""] + ([description, ""] if description else [])
    lines += [f"![learning curves]({CURVES_PNG})", ""]
    penalties = any(math.isfinite(r["final_penalised_iqm"]) for r in summary)
    lines += [f"![penalised evaluation episodes]({PENALISED_PNG})", ""] * penalties
    header = ["configuration", "seeds", "eval episodes", "AUC, IQM", "final success, IQM"]
    header += ["final penalised episodes, IQM"] * penalties + ["at env steps"]
    header += [f"env steps to {round(t * 100)}%" for t in THRESHOLDS] + ["wall time [s]"]
    align = ["---", "---:", "---:", "---", "---"] + ["---"] * penalties + ["---:"]
    align += ["---"] * len(THRESHOLDS) + ["---:"]
    lines += ["| " + " | ".join(header) + " |", "| " + " | ".join(align) + " |"]
    for r, label in zip(summary, config_labels([row_key(r) for r in summary]), strict=True):
        cells = [
            label,
            str(r["seeds"]),
            r["eval_episodes"],
            _interval(r, "auc"),
            _interval(r, "final_success"),
        ]
        cells += [_interval(r, "final_penalised")] * penalties + [f"{r['final_env_steps']:,}"]
        for pct in (round(t * 100) for t in THRESHOLDS):
            median = r[f"env_steps_to_{pct}_km_median"]
            shown = f"{median:,.0f}" if math.isfinite(median) else f"> {r['final_env_steps']:,}"
            cells.append(f"{shown} ({r[f'seeds_reaching_{pct}']}/{r['seeds']})")
        cells.append(f"{r['wall_time_s_mean']:.0f}")
        lines.append("| " + " | ".join(cells) + " |")
    lines += [
        "",
        _HOW_TO_READ.format(
            resamples=st.RESAMPLES,
            seed=st.SEED,
            final=FINAL_EVALS,
            thresholds=" / ".join(f"{round(t * 100)}%" for t in THRESHOLDS),
        ),
        "",
    ]
    if eval_summary:
        lines += (
            ["## Evaluation-only arms", ""] + ev.markdown_table(eval_summary) + ["", _HOW_TO_READ_EVALS, ""]
        )
        keys = sorted({s["perturb_key"] for s in eval_summary if s["perturb_key"]})
        lines += [f"![success under {key}](robustness__{key}.png)" for key in keys] + [""] * bool(keys)
    if registered:
        lines += ["## Pre-registered comparisons", ""]
        header = [
            "a vs b",
            "metric",
            "seeds",
            "effect [95%]",
            "P(a > b) [95%]",
            "p",
            "p method",
            "p (Holm)",
            "MDE",
            "verdict",
            "flags",
        ]
        lines += [
            "| " + " | ".join(header) + " |",
            "| --- | --- | ---: | --- | --- | ---: | --- | ---: | ---: | --- | --- |",
        ]
        sides = {"greater": ">", "less": "<", "two-sided": "vs"}
        for c in compared:
            cells = [
                f"{c['a']} {sides[c['direction']]} {c['b']}",
                c["metric"],
                f"{c['seeds_a']}/{c['seeds_b']}",
                f"{c['effect']:+.3f} [{c['effect_ci_low']:+.3f}, {c['effect_ci_high']:+.3f}]",
                f"{c['poi']:.2f} [{c['poi_ci_low']:.2f}, {c['poi_ci_high']:.2f}]",
                f"{c['p']:.3g}",
                c["p_method"],
                f"{c['p_holm']:.3g}",
                f"{c['mde']:.3f}",
                c["verdict"],
                c["flags"],
            ]
            lines.append("| " + " | ".join(cells) + " |")
        if len(compared) < registered:
            lines += [
                "",
                f"{registered - len(compared)} registered comparison(s) have no runs of an arm yet.",
            ]
        lines += [
            "",
            _HOW_TO_READ_COMPARISONS.format(
                m=registered, alpha=st.ALPHA, power=st.POWER, margin=st.BOUND_MARGIN
            ),
            "",
            f"![AUC performance profile]({PROFILE_PNG})",
            "",
        ]
    if failed:
        lines += [f"Failed runs (error.txt in their folders): {', '.join(failed)}.", ""]
    if empty:
        lines += [f"Runs without evaluations (left out): {', '.join(empty)}.", ""]
    data = f"[{RESULTS_CSV}]({RESULTS_CSV}) (one row per run and evaluation), [{SUMMARY_CSV}]({SUMMARY_CSV})"
    if compared:
        data += f", [{COMPARISONS_CSV}]({COMPARISONS_CSV})"
    lines.append(f"Data: {data}. Regenerate with `tsrl report {results_dir}`.\n")
    return "\n".join(lines)


_HOW_TO_READ_EVALS = (
    "Evaluation-only arms (the experiment file's [[evaluate]]): each seed's final policy of the trained "
    "arm on the named task (with a swept perturbation, `name@value`), over deterministic episodes whose "
    "goals no training evaluation saw, the same episodes for every arm of a run; success counts "
    "info['true_success'] where the task reports it. Success: IQM across seeds of the seeds' success "
    "rates [95% stratified-bootstrap interval]; mean: their plain mean; seeds >= 0.95: seeds whose own "
    f"success rate reached it. Data: [{ev.EVALUATIONS_CSV}]({ev.EVALUATIONS_CSV}) (one row per arm and "
    f"seed), [{ev.EVAL_SUMMARY_CSV}]({ev.EVAL_SUMMARY_CSV})."
)


def _eval_labels(table: dict[str, Any]) -> list[str]:
    """The arm labels of one [[evaluate]] entry of experiment.json (as Evaluation.labels)."""
    perturb = table.get("perturb")
    if not perturb:
        return [table["name"]]
    return [f"{table['name']}@{v:g}" for v in perturb["values"]]


def _has_penalties(all_curves: list[Curve]) -> bool:
    """Whether any run recorded penalised evaluation episodes (a task with penalties)."""
    return any(c.penalised is not None and np.isfinite(c.penalised).any() for c in all_curves)


def _interval(row: dict[str, Any], stat: str) -> str:
    point, lo, hi = row[f"{stat}_iqm"], row[f"{stat}_ci_low"], row[f"{stat}_ci_high"]
    if math.isnan(point):
        return "—"
    return f"{point:.2f} [{lo:.2f}, {hi:.2f}]"


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return value


def _experiment_info(results_dir: Path) -> dict[str, Any]:
    """experiment.json as written by `tsrl experiment` ({} without one); InvalidConfig, one line, if it is
    empty or not a JSON object."""
    path = results_dir / EXPERIMENT_FILE
    if not path.is_file():
        return {}
    try:
        info = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        info, why = None, f"not JSON ({err})"
    else:
        why = f"a JSON {type(info).__name__}"
    if not isinstance(info, dict):
        raise InvalidConfig(
            f"{path}: {why}; accepted: the JSON object `tsrl experiment` writes (run it again to rewrite "
            "the file, or remove it)"
        )
    return info


def _experiment_name(results_dir: Path) -> str:
    return _experiment_info(results_dir).get("name") or results_dir.resolve().name
