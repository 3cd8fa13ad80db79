"""Evaluations after training: an experiment's evaluation-only arms ([[evaluate]]: "train on A, evaluate
on B", optionally over a swept perturbation) and `tsrl evaluate --perturb`'s robustness profiles, with
their tables, statistics across seeds and plots.

One row per (arm label, run): the run's final policy on the arm's task over its episodes. Across seeds
an arm is summarised as the report summarises trained arms: the IQM of the seeds' success rates with
its 95% stratified-bootstrap interval (tsrl.experiments.statistics), plus how many seeds reached 95%.
Only torch-free imports at module level: `tsrl report` reads the tables without loading a policy.
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from ..agents.config import TrainConfig
from ..agents.run_folder import CONFIG_FILE, load_config, with_task_copy
from ..agents.transfer import EvalTask, Perturbation, check_layout, eval_task, sweep
from ..exceptions import InvalidConfig
from ..files import write_atomic
from . import statistics as st
from .config import WORKER_ENV, ExperimentConfig, Key, evaluation_tasks

EVALUATIONS_CSV = "evaluations.csv"
EVAL_SUMMARY_CSV = "evaluations_summary.csv"
#: Per-seed success at or above this counts in `seeds_at_95` (the issue's transfer target).
TARGET = 0.95
EVAL_COLUMNS: tuple[str, ...] = (
    "label",
    "evaluation",
    "arm",
    "task",
    "perturb_key",
    "perturb_value",
    "seed",
    "env_steps",
    "episodes",
    "success_rate",
    "final_distance_m",
    "penalised_rate",
    "wall_time_s",
)


# -- computing rows ---------------------------------------------------------------------------------
def evaluation_rows(
    run_dir: Path,
    tasks: list[EvalTask],
    labels: list[str],
    evaluation: str,
    arm: str,
    perturbation: Perturbation | None,
    episodes: int,
    seed: int | None = None,
    fresh: bool = False,
) -> list[dict[str, Any]]:
    """One row per task: the run's newest usable policy on it (tsrl.agents.evaluation.evaluate_run_on)."""
    from ..agents.evaluation import evaluate_run_on

    t0 = time.monotonic()
    results = evaluate_run_on(run_dir, tasks, episodes, seed, fresh=fresh)
    seconds = (time.monotonic() - t0) / len(tasks)
    cfg = load_config(run_dir)
    values: list[float | None] = (
        list(perturbation.values) if perturbation is not None else [None] * len(tasks)
    )
    return [
        {
            "label": label,
            "evaluation": evaluation,
            "arm": arm,
            "task": r.task,
            "perturb_key": perturbation.key if perturbation is not None else "",
            "perturb_value": math.nan if value is None else value,
            "seed": cfg.seed,
            "env_steps": r.env_steps,
            "episodes": r.result.episodes,
            "success_rate": r.result.success_rate,
            "final_distance_m": r.result.mean_final_distance,
            "penalised_rate": r.result.penalised_rate,
            "wall_time_s": seconds,
        }
        for label, r, value in zip(labels, results, values, strict=True)
    ]


def run_evaluations(exp: ExperimentConfig, exp_dir: Path, stream: TextIO, workers: int = 1) -> Path | None:
    """The [[evaluate]] arms of `exp` on the finished runs in `exp_dir`, into evaluations.csv (written
    after each run: an interrupted phase resumes; rows of a run at the same checkpoint and episodes are
    kept, not recomputed). Runs not at their budget are left out and said. With `workers` > 1 the
    runs' evaluations go to that many spawned processes (one torch thread each); the rows, each from
    its own seeded episodes, are the same, and the file lists them in one order either way (by
    label, as `exp.eval_arms()` orders them, then seed). Returns the file, None without [[evaluate]]."""
    from .runner import checkpoint_steps

    if not exp.evaluate:
        return None
    path = exp_dir / EVALUATIONS_CSV
    table = {(r["label"], int(r["seed"])): r for r in read_evaluations(path)}
    order = {label: i for i, label in enumerate(exp.eval_arms())}
    jobs: list[tuple[Any, ...]] = []
    for e in exp.evaluate:
        tasks, labels = evaluation_tasks(exp, e), e.labels()
        for cfg in exp.arm_runs(e.arm, exp_dir.resolve()):
            run_dir = exp_dir / cfg.run_name
            steps = checkpoint_steps(run_dir) if run_dir.is_dir() else 0
            if steps < cfg.total_timesteps:
                print(f"evaluate {e.name}: {cfg.run_name} is not at its budget yet; left out", file=stream)
                continue
            old = [table.get((label, cfg.seed)) for label in labels]
            if all(
                r is not None and int(r["env_steps"]) == steps and int(r["episodes"]) == e.episodes
                for r in old
            ):
                continue
            jobs.append((run_dir, tasks, labels, e.name, e.arm, e.perturb, e.episodes))

    def keep(run_name: str, rows: list[dict[str, Any]]) -> None:
        for row in rows:
            table[row["label"], int(row["seed"])] = row
        kept = [r for k, r in table.items() if k[0] in order]
        write_evaluations(path, sorted(kept, key=lambda r: (order[r["label"]], int(r["seed"]))))
        shown = ", ".join(f"{r['label']} {r['success_rate']:.2f}" for r in rows)
        print(f"evaluated {run_name}: {shown}", file=stream)

    if workers <= 1 or len(jobs) <= 1:
        for job in jobs:
            keep(*_evaluate_job(job))
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(
            min(workers, len(jobs)), mp_context=mp.get_context("spawn"), initializer=_one_thread
        ) as pool:
            futures = [pool.submit(_evaluate_job, job) for job in jobs]
            try:
                for future in as_completed(futures):
                    keep(*future.result())
            except BaseException:  # a signal (ExperimentStopped) or an error: stop now, none starts
                running = list((pool._processes or {}).values())  # public only from Python 3.14 on
                pool.shutdown(wait=False, cancel_futures=True)
                for process in running:
                    process.terminate()  # the running ones end (the rows kept so far stay in the file)
                raise
    return path if path.is_file() else None


def _evaluate_job(job: tuple[Any, ...]) -> tuple[str, list[dict[str, Any]]]:
    """The run's name and evaluation_rows of one (run, [[evaluate]] arm), with fresh episodes."""
    run_dir, tasks, labels, evaluation, arm, perturbation, episodes = job
    rows = evaluation_rows(run_dir, tasks, labels, evaluation, arm, perturbation, episodes, fresh=True)
    return run_dir.name, rows


def _one_thread() -> None:
    """A spawned evaluation worker: one thread per BLAS/OpenMP pool and for torch."""
    import os

    os.environ.update(WORKER_ENV)
    import torch

    torch.set_num_threads(1)


def profile(
    path: Path,
    perturbation: Perturbation,
    episodes: int,
    seed: int | None = None,
    env_id: str | None = None,
) -> list[dict[str, Any]]:
    """`tsrl evaluate PATH --perturb`: rows of every run in `path` (a run folder, or an experiment's
    results folder: each of its runs, labelled by configuration) on the sweep of `perturbation` over
    the task `env_id` (default: each run's own). Every run's layout and every value are checked before
    any policy loads."""
    from .config import config_labels
    from .results import find_runs, variants

    run_dirs = [path] if (path / CONFIG_FILE).is_file() else find_runs(path)
    cfgs = [load_config(d) for d in run_dirs]
    keys: list[Key] = [
        (c.env_id, c.obs, c.action, c.agent.algo, v) for c, v in zip(cfgs, variants(cfgs), strict=True)
    ]
    arms = config_labels(keys) if len(run_dirs) > 1 else [cfgs[0].run_name]
    plans: list[tuple[Path, TrainConfig, str, list[EvalTask]]] = []
    for run_dir, cfg, arm in zip(run_dirs, cfgs, arms, strict=True):
        recorded = with_task_copy(run_dir, cfg, notify=False)  # on its recorded task (agents.task_record)
        tasks = sweep(eval_task(recorded, env_id), perturbation)
        for t in tasks:
            check_layout(recorded, t)
        plans.append((run_dir, cfg, arm, tasks))
    rows = []
    for run_dir, _, arm, tasks in plans:
        labels = [f"{arm}@{v:g}" for v in perturbation.values]
        rows += evaluation_rows(run_dir, tasks, labels, arm, arm, perturbation, episodes, seed)
    return rows


def write_profile(
    path: Path,
    perturbation: Perturbation,
    episodes: int,
    seed: int | None = None,
    env_id: str | None = None,
    out: Path | None = None,
) -> list[str]:
    """`tsrl evaluate PATH --perturb`: profile()'s rows as a CSV table (`out`, by default
    PATH/perturb__KEY[__ENV].csv) and a plot beside it (.png); returns the lines to print (the
    summary as markdown, the files written). Nothing is written if any input is bad."""
    rows = profile(path, perturbation, episodes, seed, env_id)
    if out is None:
        where = (
            ""
            if env_id is None
            else "__" + Path(env_id).stem
            if env_id.endswith(".toml")
            else "__" + env_id.replace("/", "-")
        )
        out = path / f"perturb__{perturbation.key}{where}.csv"
    summary = summarize_evaluations(rows)
    table = write_table(out, summary, list(summary[0]))
    (plot,) = plot_profiles(summary, rows, lambda key: out.with_suffix(".png"))
    runs = out.with_name(out.stem + "__runs.csv")
    return [
        *markdown_table(summary),
        "",
        f"wrote {table}",
        f"wrote {write_evaluations(runs, rows)}",
        f"wrote {plot}",
    ]


# -- files ------------------------------------------------------------------------------------------
def read_evaluations(path: Path) -> list[dict[str, Any]]:
    """evaluations.csv's rows (numbers as floats, NaN for empty cells; seed and counts as ints).

    Raises InvalidConfig, one line naming the file, row and column, where a cell is missing or not a
    number of its column's kind (a damaged or hand-edited file)."""
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for line, r in enumerate(rows, start=2):
        for k, kind in _EVAL_NUMBERS.items():
            value = r.get(k)
            try:
                r[k] = math.nan if value == "" and kind is float else kind(value)
            except (TypeError, ValueError):
                accepted = "a whole number" if kind is int else "a number or an empty cell"
                raise InvalidConfig(
                    f"{path}: row {line}: {k} = {value!r}; accepted: {accepted} (the file as `tsrl experiment` "
                    "writes it: remove it to evaluate again)"
                ) from None
    return rows


#: evaluations.csv's numeric columns and their kinds (the others are labels).
_EVAL_NUMBERS: dict[str, type] = {
    "seed": int,
    "env_steps": int,
    "episodes": int,
    "perturb_value": float,
    "success_rate": float,
    "final_distance_m": float,
    "penalised_rate": float,
    "wall_time_s": float,
}


def write_evaluations(path: Path, rows: list[dict[str, Any]]) -> Path:
    """Writes `rows` (EVAL_COLUMNS) atomically."""
    return write_table(path, rows, EVAL_COLUMNS)


def write_table(path: Path, rows: list[dict[str, Any]], columns: tuple[str, ...] | list[str]) -> Path:
    """A CSV of `rows` with `columns`, written whole (tsrl.files.write_atomic); NaN as an empty cell."""
    import io

    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: _cell(r.get(k, "")) for k in columns})
    write_atomic(path, out.getvalue())
    return path


# -- statistics and tables --------------------------------------------------------------------------
def per_seed_success(rows: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Per arm label, its seeds' success rates (in seed order)."""
    out: dict[str, list[tuple[int, float]]] = {}
    for r in rows:
        out.setdefault(r["label"], []).append((r["seed"], r["success_rate"]))
    return {label: np.array([v for _, v in sorted(pairs)]) for label, pairs in out.items()}


def summarize_evaluations(rows: list[dict[str, Any]], order: list[str] | None = None) -> list[dict[str, Any]]:
    """One row per arm label (in `order`, else first appearance): seeds, IQM of success with its
    interval, seeds at or above TARGET, mean final distance, episodes per seed."""
    success = per_seed_success(rows)
    labels = [label for label in (order or list(success)) if label in success]
    out = []
    for label in labels:
        mine = [r for r in rows if r["label"] == label]
        est = st.iqm_interval(success[label])
        first = mine[0]
        out.append(
            {
                "label": label,
                "evaluation": first["evaluation"],
                "arm": first["arm"],
                "task": first["task"],
                "perturb_key": first["perturb_key"],
                "perturb_value": first["perturb_value"],
                "seeds": len(mine),
                "episodes": "/".join(sorted({str(r["episodes"]) for r in mine})),
                "success_iqm": float(est.point[0]),
                "success_ci_low": float(est.low[0]),
                "success_ci_high": float(est.high[0]),
                "success_mean": float(np.mean(success[label])),
                "seeds_at_95": int(np.sum(success[label] >= TARGET)),
                "final_distance_mean_m": float(np.nanmean([r["final_distance_m"] for r in mine])),
                "env_steps": "/".join(sorted({str(r["env_steps"]) for r in mine})),
            }
        )
    return out


def markdown_table(summary: list[dict[str, Any]]) -> list[str]:
    """The summary as markdown lines."""
    header = "| arm | trained | evaluated on | seeds | episodes | success, IQM [95%] | mean | seeds >= 0.95 |"
    lines = [
        header + " final distance [m] |",
        "| --- | --- | --- | ---: | ---: | --- | ---: | ---: | ---: |",
    ]
    for s in summary:
        ci = f"{s['success_iqm']:.2f} [{s['success_ci_low']:.2f}, {s['success_ci_high']:.2f}]"
        lines.append(
            f"| {s['label']} | {s['arm']} | {s['task']} | {s['seeds']} | {s['episodes']} | {ci} | "
            f"{s['success_mean']:.3f} | {s['seeds_at_95']}/{s['seeds']} | {s['final_distance_mean_m']:.4f} |"
        )
    return lines


def plot_profiles(
    summary: list[dict[str, Any]], rows: list[dict[str, Any]], out_for: Callable[[str], Path]
) -> list[Path]:
    """One PNG per swept key (`out_for(key)`): success against the key's value, one line per
    evaluation (IQM across seeds with its interval; dots: seeds)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..agents.plotting import save_success_plot

    paths = []
    for key in sorted({s["perturb_key"] for s in summary if s["perturb_key"]}):
        fig, ax = plt.subplots(figsize=(6.5, 4.2), dpi=120)
        names = list(dict.fromkeys(s["evaluation"] for s in summary if s["perturb_key"] == key))
        for i, name in enumerate(names):
            points = [s for s in summary if s["evaluation"] == name and s["perturb_key"] == key]
            points.sort(key=lambda s: s["perturb_value"])
            xs = np.array([s["perturb_value"] for s in points])
            colour = f"C{i}"
            n = points[0]["seeds"]
            ax.plot(xs, [s["success_iqm"] for s in points], "o-", color=colour, label=f"{name} ({n} seeds)")
            if n > 1:
                ax.fill_between(
                    xs,
                    [s["success_ci_low"] for s in points],
                    [s["success_ci_high"] for s in points],
                    color=colour,
                    alpha=0.2,
                    linewidth=0,
                )
            seeds = [r for r in rows if r["evaluation"] == name and r["perturb_key"] == key]
            jitter = (np.ptp(xs) or 1.0) * 0.01 * (i - (len(names) - 1) / 2)
            ax.scatter(
                [r["perturb_value"] + jitter for r in seeds],
                [r["success_rate"] for r in seeds],
                color=colour,
                s=6,
                alpha=0.4,
            )
        title = f"success under {key}\nIQM across seeds, 95% stratified-bootstrap interval; dots: seeds"
        paths.append(save_success_plot(fig, ax, out_for(key), xlabel=key, title=title, fontsize=9))
    return paths


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    return value
