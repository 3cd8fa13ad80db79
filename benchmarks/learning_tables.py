"""The learning benchmarks' tables (benchmarks/learning.py, family.py) from run folders: env steps and
seconds to 50/90/95 % evaluation success per seed and the mean with its 95% Student-t interval, and the
suites' verdict lines. Reads only each run's progress.csv and config.json (stdlib and numpy), so that
scripts/benchmark_tables.py re-derives the tables from the copies `save_runs` commits under
docs/results/benchmarks/NAME/<group>/<run>/.
"""

from __future__ import annotations

import csv
import json
import math
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from tsrl.agents.config import LEARNER_PRESETS, TASK_FILE_SUFFIX

THRESHOLDS = (0.5, 0.9, 0.95)
#: The manipulation family (benchmarks/family.py): task -> (target budget [env steps], evaluation
#: every [env steps]); the target is met when every seed reaches 95 % within its budget.
FAMILY_TASKS: dict[str, tuple[int, int]] = {
    "PandaPush-v0": (30_000, 2_500),
    "PandaPickPlaceGripper-v0": (60_000, 2_500),
    "PandaStack-v0": (150_000, 10_000),
    "PandaPegInsert-v0": (150_000, 10_000),
}
#: A run folder's files that its table is made of.
RUN_FILES = ("progress.csv", "config.json")
PANDA = "tsrl/PandaReach-v0"
UR5E = "tsrl/UR5eReach-v0"
#: The own-robot target: every seed at this evaluation success within the budget.
OWN_ROBOT_TARGET = 0.9
#: Issue 27's reach target: every seed at 95 % evaluation success within this many env steps.
REACH_TARGET_STEPS = 1_000
#: Issue 27's pick-and-place target: every seed at 95 % evaluation success within this many env steps.
ABLATION_BUDGET = 12_500


def read_progress_csv(run_dir: Path) -> list[dict[str, float]]:
    """A run's progress.csv rows, every column a float (an empty cell NaN)."""
    with open(run_dir / "progress.csv", newline="") as f:
        return [{k: float(v) if v != "" else math.nan for k, v in r.items()} for r in csv.DictReader(f)]


def save_runs(run_dirs: list[Path], out: Path, group: Callable[[Path], str] | None = None) -> None:
    """Copies each run's RUN_FILES to out/<group(run folder), default its parent folder's name>/<run name>/."""
    for run_dir in run_dirs:
        dest = out / (group(run_dir) if group else run_dir.parent.name) / run_dir.name
        dest.mkdir(parents=True, exist_ok=True)
        for name in RUN_FILES:
            shutil.copyfile(run_dir / name, dest / name)


def saved_runs(data_dir: Path) -> list[Path]:
    """The run folders under `data_dir` (as `save_runs` lays them out), sorted by path."""
    return sorted(p.parent for p in data_dir.glob("*/*/progress.csv"))


def first_reaching(
    rows: list[dict[str, float]], threshold: float, train_time: bool = False
) -> tuple[float, float]:
    """(env steps, wall time s) of the first evaluation with success >= threshold; NaN if none.

    With `train_time`, the wall time leaves the evaluations out.
    """
    for r in rows:
        if r["eval_success_rate"] >= threshold:
            return r["env_steps"], r["wall_time_s"] - (r["eval_time_s"] if train_time else 0.0)
    return math.nan, math.nan


def mean_ci95(values: np.ndarray) -> tuple[float, float]:
    """Mean over seeds and the half-width of its 95% Student-t interval (0 for one seed). Learning
    curves and studies use the IQM and bootstrap interval of tsrl.experiments.statistics."""
    from scipy.stats import t

    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return float(values.mean()), 0.0
    sem = values.std(ddof=1) / math.sqrt(len(values))
    return float(values.mean()), float(t.ppf(0.975, len(values) - 1) * sem)


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


def _steps(x: float) -> str:
    return "never" if not math.isfinite(x) else f"{x:,.0f}"


def _whole(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.0f}"


def _seed(run_dir: Path) -> int:
    return int(json.loads((run_dir / "config.json").read_text())["seed"])


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
    for run_dir in sorted(run_dirs, key=_seed):
        rows = read_progress_csv(run_dir)
        reached = [first_reaching(rows, t, train_time) for t in THRESHOLDS]
        last = rows[-1]
        training = last["wall_time_s"] - (0.0 if math.isnan(last["eval_time_s"]) else last["eval_time_s"])
        rate = last["env_steps"] / training if training > 0 else math.nan
        per_seed.append((reached, last["eval_success_rate"], rate))
        cells = [_steps(s) for s, _ in reached] + [_whole(w) for _, w in reached]
        lines.append(
            f"| {_seed(run_dir)} | {' | '.join(cells)} | {last['eval_success_rate']:.2f} | {rate:.0f} |"
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
        f"UR5e env steps to 95%: {', '.join(_steps(x) for x in ur5e)} (mean {np.mean(ur5e):,.0f}; twice that "
        f"{limit:,.0f}). Panda: {', '.join(_steps(x) for x in panda)}; every Panda seed within twice the "
        f"UR5e's mean: {'yes' if ok else 'no'}."
    )
    return [line]


def every_seed_reaches(run_dirs: list[Path], threshold: float, budget: int) -> list[str]:
    """Each seed's env steps to `threshold` evaluation success and whether all got there within `budget`."""
    steps = [first_reaching(read_progress_csv(d), threshold)[0] for d in sorted(run_dirs, key=_seed)]
    ok = all(math.isfinite(s) and s <= budget for s in steps)
    return [
        f"Env steps to {threshold:.0%}: {', '.join(_steps(s) for s in steps)}; every seed within {budget:,}: {'yes' if ok else 'no'}."
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


def common_aucs(
    curves: dict[str, list[list[dict[str, float]]]],
) -> tuple[list[float], dict[str, np.ndarray]]:
    """(the env steps at which every run of every variant was evaluated, per variant its seeds' AUC
    over those evaluations (n seeds,)); curves: variant -> its runs' progress rows."""
    from tsrl.experiments import statistics as st

    steps = sorted(set.intersection(*({r["env_steps"] for r in c} for cs in curves.values() for c in cs)))
    aucs = {
        v: st.area_under_curve(
            np.array(steps),
            np.array([[{r["env_steps"]: r["eval_success_rate"] for r in c}[x] for x in steps] for c in cs]),
        )
        for v, cs in curves.items()
    }
    return steps, aucs


def ablation_table(variants: dict[str, list[Path]], budget: int, reference: str = "fast") -> list[str]:
    """The learner ablation (issue 27): per variant ("fast", "without-<option>") its seeds' env steps to
    95 % success, success at `budget` env steps (the target), IQM of AUC over the evaluations every run
    has, the `reference` variant's IQM minus the variant's (the option's contribution: > 0 means it
    helps) and the median training seconds to `budget` (evaluations excluded)."""
    from tsrl.experiments import statistics as st

    curves = {v: [read_progress_csv(d) for d in sorted(dirs, key=_seed)] for v, dirs in variants.items()}
    steps, aucs = common_aucs(curves)
    lines = [
        f"| variant | seeds | env steps to 95 % | success at {budget:,} | AUC, IQM [95%] | {reference} minus variant, AUC | training s to {budget:,} (median) |",
        "| --- | ---: | --- | --- | --- | --- | ---: |",
    ]
    for v, cs in curves.items():
        at_budget = [{r["env_steps"]: r for r in c}.get(float(budget)) for c in cs]
        success = ", ".join("-" if r is None else f"{r['eval_success_rate']:.2f}" for r in at_budget)
        seconds = [r["wall_time_s"] - r["eval_time_s"] for r in at_budget if r is not None]
        reached = ", ".join(_steps(first_reaching(c, THRESHOLDS[-1])[0]) for c in cs)
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


# The renderers that meta.json names ("benchmarks/learning_tables.py:table_<kind>"), one per kind.


def saved_variants(data_dir: Path) -> dict[str, list[Path]]:
    """The run folders of a data folder laid out <variant>/<run>/, by variant."""
    variants: dict[str, list[Path]] = {}
    for run_dir in saved_runs(data_dir):
        variants.setdefault(run_dir.parent.name, []).append(run_dir)
    return variants


def table_ablation(data_dir: Path) -> list[str]:
    """`ablation_table` of a data folder laid out <variant>/<run>/ (benchmarks/learning.py learner-ablation)."""
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


def family_label(env_id: str) -> str:
    """A family run's environment as its tables name it: the id, or a task file's file name (its
    path is the machine's)."""
    return Path(env_id).name if env_id.endswith(TASK_FILE_SUFFIX) else env_id


def family_variant(config: dict[str, Any]) -> list[str]:
    """What sets a family run (benchmarks/family.py; its config.json as a dict) apart from the paper's
    agent (DDPG) with 100 demonstrations, e.g. ["learner fast"], ["TQC", "learner fast"], ["learner fast",
    "UTD 4"], ["resets 0.5", "reverse curriculum over 100,000"]; [] for that agent. Its run name does not
    say the resets, the UTD or the demonstration count."""
    demos = config["agent"]["demos"]
    count = Path(demos["path"] or "").stem.rsplit("-", 1)[-1]
    learner = config["agent"].get("learner", "paper")
    resets, curriculum = demos.get("reset_prob"), demos.get("reset_curriculum_steps", 0)
    algo = config["agent"]["algo"]
    extra = [algo.upper()] if algo != "ddpg" else []
    extra += [f"learner {learner}"] if learner != "paper" else []
    preset_utd = LEARNER_PRESETS[learner]["utd"]
    utd = config["agent"].get("utd", preset_utd)
    extra += [f"UTD {utd:g}"] if utd != preset_utd else []
    extra += [f"resets {resets}"] if resets else []
    extra += [f"reverse curriculum over {curriculum:,}"] if resets and curriculum else []
    paced = demos.get("reset_curriculum_success", 0.0)
    extra += [f"reverse curriculum paced by success {paced:g}"] if resets and paced else []
    extra += [f"{count} demonstrations"] if count.isdigit() and int(count) != 100 else []
    action_l2 = config["agent"].get("action_l2", 0.0)
    extra += [f"action penalty {action_l2:g}"] if action_l2 else []
    budget, target = int(config["total_timesteps"]), family_target(config["env_id"])
    extra += [f"budget {budget:,}"] if target is not None and budget != target else []
    return extra


def family_target(env_id: str) -> int | None:
    """The target budget [env steps] of the family task a run's env_id is or varies (FAMILY_TASKS;
    a task file by its `solver`, read from benchmarks/task_files/), None for any other task."""
    if env_id.endswith(TASK_FILE_SUFFIX):
        if not _family_task_file(env_id).is_file():
            return None
        env_id = compared_task(env_id)[0]
    task = FAMILY_TASKS.get(env_id.removeprefix("tsrl/"))
    return None if task is None else task[0]


def every_seed_within(steps_to_95: list[float], target: int) -> bool:
    """The family's target rule: every seed reached 95 % (env steps, NaN where never) within `target`."""
    return all(not math.isnan(steps) and steps <= target for steps in steps_to_95)


def _family_task_file(env_id: str) -> Path:
    """Where benchmarks/task_files/ keeps a task-file run's file (by its name: a run's path is its
    machine's)."""
    return Path(__file__).resolve().parent / "task_files" / Path(env_id).name


def compared_task(env_id: str) -> tuple[str, list[str]]:
    """(the family task, what the run's task adds to it) of a family run's env_id: the id itself and
    nothing, or for a task file (benchmarks/task_files/, by file name: a run's path is its machine's)
    the tsrl id of its `solver`, the family task it varies, and the file's name. Raises SystemExit
    naming the file where it is not under benchmarks/task_files/."""
    if not env_id.endswith(TASK_FILE_SUFFIX):
        return env_id, []
    from tsrl.envs import load_task

    name = Path(env_id).name
    path = _family_task_file(env_id)
    if not path.is_file():
        raise SystemExit(f"{env_id}: no task file {name!r} in {path.parent}; accepted: one of its files")
    return f"tsrl/{load_task(str(path)).solver}", [name]


def table_family(data_dir: Path) -> list[str]:
    """The manipulation family's summary (benchmarks/family.py): per task, its target budget
    (FAMILY_TASKS; a run past it names its own budget), the seeds run, each seed's success at the
    budget, env steps to 50 % and to 95 %, seconds of training (evaluations left out) to 95 %, and whether every seed reached 95 %
    within the target."""
    lines = [
        "| task | target: every seed at 95 % within | seeds run | success at the budget | env steps to 50 % | env steps to 95 % | s of training to 95 % | every seed at 95 % |",
        "| --- | ---: | --- | --- | --- | --- | --- | --- |",
    ]
    by_task: dict[str, list[Path]] = {}
    for run_dir in saved_runs(data_dir):
        config = json.loads((run_dir / "config.json").read_text())
        extra = family_variant(config)
        name = f"`{family_label(config['env_id'])}`" + (f" ({', '.join(extra)})" if extra else "")
        by_task.setdefault(name, []).append(run_dir)
    for task, run_dirs in by_task.items():
        run_dirs = sorted(run_dirs, key=_seed)
        env_id = json.loads((run_dirs[0] / "config.json").read_text())["env_id"]
        target = family_target(env_id)
        if target is None:
            raise SystemExit(
                f"{run_dirs[0]}: env_id {env_id!r} is no family task; accepted: {', '.join(FAMILY_TASKS)}"
            )
        progress = [read_progress_csv(d) for d in run_dirs]
        final = ", ".join(f"{rows[-1]['eval_success_rate']:.2f}" for rows in progress)
        half = ", ".join(_steps(first_reaching(rows, 0.5)[0]) for rows in progress)
        at_95 = [first_reaching(rows, 0.95, train_time=True) for rows in progress]
        steps_95 = ", ".join(_steps(steps) for steps, _ in at_95)
        seconds_95 = ", ".join(_whole(seconds) for _, seconds in at_95)
        met = every_seed_within([steps for steps, _ in at_95], target)
        seeds = ", ".join(str(_seed(d)) for d in run_dirs)
        lines.append(
            f"| {task} | {target:,} | {seeds} | {final} | {half} | {steps_95} | {seconds_95} | {'yes' if met else 'no'} |"
        )
    return lines


def table_family_comparison(data_dir: Path) -> list[str]:
    """Variants of one family task compared (benchmarks/merge_saved.py --table): per variant (what
    `family_variant` says sets it apart) its seeds, success at the budget, env steps to 95 % and IQM of
    AUC over the evaluations every run has, and each variant's IQM minus the baseline's (the variant
    that adds least) with its 95% stratified-bootstrap interval: *helps* above 0, *hurts* below 0,
    else *not decided*. A task file's runs are a variant of the family task it varies. Raises SystemExit naming the folder when it holds several tasks or no single
    baseline."""
    from tsrl.experiments import statistics as st

    variants: dict[str, list[Path]] = {}
    tasks, extras = set(), {}
    for run_dir in saved_runs(data_dir):
        config = json.loads((run_dir / "config.json").read_text())
        task, task_extra = compared_task(config["env_id"])
        tasks.add(task)
        extra = task_extra + family_variant(config)
        label = ", ".join(extra) or "learner paper"
        extras[label] = len(extra)
        variants.setdefault(label, []).append(run_dir)
    fewest = min(extras.values(), default=0)
    baselines = [v for v, n in extras.items() if n == fewest]
    if len(tasks) != 1 or len(baselines) != 1:
        raise SystemExit(
            f"{data_dir}: tasks {sorted(tasks)}, variants adding least {baselines}; accepted: one task "
            "and one variant that adds least (the baseline)"
        )
    baseline = baselines[0]
    curves = {v: [read_progress_csv(d) for d in sorted(dirs, key=_seed)] for v, dirs in variants.items()}
    steps, aucs = common_aucs(curves)
    header = f"| `{tasks.pop()}` | seeds | success at the budget | env steps to 95 % | AUC, IQM [95%] "
    lines = [
        header + f"| minus {baseline}, AUC IQM [95%] | decided |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for v in sorted(curves, key=lambda v: (v != baseline, v)):
        runs = curves[v]
        seeds = ", ".join(str(_seed(d)) for d in sorted(variants[v], key=_seed))
        final = ", ".join(f"{rows[-1]['eval_success_rate']:.2f}" for rows in runs)
        reached = ", ".join(_steps(first_reaching(rows, THRESHOLDS[-1])[0]) for rows in runs)
        e = st.iqm_interval(aucs[v])
        diff, decided = "-", "-"
        if v != baseline:
            d = st.iqm_difference(aucs[v], aucs[baseline])
            diff = f"{d.point[0]:+.3f} [{d.low[0]:+.3f}, {d.high[0]:+.3f}]"
            decided = "helps" if d.low[0] > 0 else "hurts" if d.high[0] < 0 else "not decided"
        lines.append(
            f"| {v} | {seeds} | {final} | {reached} | {e.point[0]:.2f} [{e.low[0]:.2f}, {e.high[0]:.2f}] "
            f"| {diff} | {decided} |"
        )
    lines += ["", f"AUC over the evaluations at {', '.join(f'{x:,.0f}' for x in steps)} env steps."]
    return lines


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
            f"| {label} | {u:.1f} | {_whole(f)} | {'-' if not math.isfinite(u / f) else f'{u / f:.0%}'} | {e:.1f} |"
        )
    return lines


def speed_table(data_dir: Path) -> list[str]:
    """The learner-speed table from the data `speed --save` wrote."""
    from record import DATA_CSV, read_rows

    return speed_render(read_rows(data_dir / DATA_CSV))
