"""The manipulation family's tables (studies/manipulation-family/README.md) from saved run folders:
per task its target and whether every seed reached 95 % within it (`table_family`), and variants of
one task compared by their AUC (`table_family_comparison`). scripts/benchmark_tables.py re-derives the
committed ones from docs/results/benchmarks/NAME/ (meta.json names the renderer).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from tsrl.agents.config import LEARNER_PRESETS, TASK_FILE_SUFFIX
from tsrl.experiments.milestones import (
    THRESHOLDS,
    common_aucs,
    first_reaching,
    read_progress_csv,
    run_seed,
    saved_runs,
    steps_text,
    whole_text,
)

#: The manipulation family (experiments/manipulation-family.toml): task -> (target budget [env steps],
#: evaluation every [env steps]); the target is met when every seed reaches 95 % within its budget.
FAMILY_TASKS: dict[str, tuple[int, int]] = {
    "PandaPush-v0": (30_000, 2_500),
    "PandaPickPlaceGripper-v0": (60_000, 2_500),
    "PandaStack-v0": (150_000, 10_000),
    "PandaPegInsert-v0": (150_000, 10_000),
}
#: The family tasks' variants (a task file whose `solver` names the family task it varies).
TASK_FILES = Path(__file__).resolve().parent / "task_files"


def family_label(env_id: str) -> str:
    """A family run's environment as its tables name it: the id, or a task file's file name (its
    path is the machine's)."""
    return Path(env_id).name if env_id.endswith(TASK_FILE_SUFFIX) else env_id


def family_variant(config: dict[str, Any]) -> list[str]:
    """What sets a family run (experiments/manipulation-family.toml or a variant of it, as benchmarks/family.py made them until it
    became that file; its config.json as a dict) apart from the paper's
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
    a task file by its `solver`, read from task_files/ beside this file), None for any other task."""
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
    """Where task_files/ beside this file keeps a task-file run's file (by its name: a run's path is
    its machine's)."""
    return TASK_FILES / Path(env_id).name


def compared_task(env_id: str) -> tuple[str, list[str]]:
    """(the family task, what the run's task adds to it) of a family run's env_id: the id itself and
    nothing, or for a task file (task_files/ beside this file, by file name: a run's path is its machine's)
    the tsrl id of its `solver`, the family task it varies, and the file's name. Raises SystemExit
    naming the file where it is not under task_files/."""
    if not env_id.endswith(TASK_FILE_SUFFIX):
        return env_id, []
    from tsrl.envs import load_task

    name = Path(env_id).name
    path = _family_task_file(env_id)
    if not path.is_file():
        raise SystemExit(f"{env_id}: no task file {name!r} in {path.parent}; accepted: one of its files")
    return f"tsrl/{load_task(str(path)).solver}", [name]


def table_family(data_dir: Path) -> list[str]:
    """The manipulation family's summary: per task, its target budget
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
        run_dirs = sorted(run_dirs, key=run_seed)
        env_id = json.loads((run_dirs[0] / "config.json").read_text())["env_id"]
        target = family_target(env_id)
        if target is None:
            raise SystemExit(
                f"{run_dirs[0]}: env_id {env_id!r} is no family task; accepted: {', '.join(FAMILY_TASKS)}"
            )
        progress = [read_progress_csv(d) for d in run_dirs]
        final = ", ".join(f"{rows[-1]['eval_success_rate']:.2f}" for rows in progress)
        half = ", ".join(steps_text(first_reaching(rows, 0.5)[0]) for rows in progress)
        at_95 = [first_reaching(rows, 0.95, train_time=True) for rows in progress]
        steps_95 = ", ".join(steps_text(steps) for steps, _ in at_95)
        seconds_95 = ", ".join(whole_text(seconds) for _, seconds in at_95)
        met = every_seed_within([steps for steps, _ in at_95], target)
        seeds = ", ".join(str(run_seed(d)) for d in run_dirs)
        lines.append(
            f"| {task} | {target:,} | {seeds} | {final} | {half} | {steps_95} | {seconds_95} | {'yes' if met else 'no'} |"
        )
    return lines


def table_family_comparison(data_dir: Path) -> list[str]:
    """Variants of one family task compared (merge_saved.py --table, beside this file): per variant (what
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
    curves = {v: [read_progress_csv(d) for d in sorted(dirs, key=run_seed)] for v, dirs in variants.items()}
    steps, aucs = common_aucs(curves)
    header = f"| `{tasks.pop()}` | seeds | success at the budget | env steps to 95 % | AUC, IQM [95%] "
    lines = [
        header + f"| minus {baseline}, AUC IQM [95%] | decided |",
        "| --- | --- | --- | --- | --- | --- | --- |",
    ]
    for v in sorted(curves, key=lambda v: (v != baseline, v)):
        runs = curves[v]
        seeds = ", ".join(str(run_seed(d)) for d in sorted(variants[v], key=run_seed))
        final = ", ".join(f"{rows[-1]['eval_success_rate']:.2f}" for rows in runs)
        reached = ", ".join(steps_text(first_reaching(rows, THRESHOLDS[-1])[0]) for rows in runs)
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
