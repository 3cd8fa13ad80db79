"""The learner-from-demonstrations study (README.md beside this file): trains one arm on one task for
the given seeds, evaluates each final policy on 100 fresh episodes, and writes a row per run to
data/runs.csv; `table` prints the study's table from that file.

    python studies/learner-from-demos/run.py train ARM TASK --seeds 0 1 2 3 4 [--out DIR]
    python studies/learner-from-demos/run.py table      # the runs' table and the pre-registered verdicts
    python studies/learner-from-demos/run.py summary    # the issue's benchmark table (docs/results.md)

Arms: bc100 / bc10: behaviour cloning of the first 100 / 10 scripted demonstrations (recording
seed 0), 8,000 gradient steps; margin100 / margin10: `--learner fast` with the same demonstrations
and `--return-bound 0` (pre-registration 8: pre-registration 6's learner with a reward at half the
task's success radius); bound100 / bound10: margin's with `--return-bound 1` (the episodes' returns
as a lower bound of the critic, tsrl.agents.return_bound; `--learner fast` itself since
pre-registration 17); adapt100 / adapt10: bound's with
`adaptive_noise` (the explore episodes' noise scaled to keep them winnable, tsrl.agents.acting_gate);
reset100 / reset10: bound's with `--demos-reset-prob 0.5` (half of the training episodes start from a
state of a demonstration, uniform over its episodes and steps; Nair et al. 2018; pre-registration 19);
distill100 / distill10: bound's with `--distill-choice 1` (the actor cloned toward its clone where the
critic's choice prefers the clone, tsrl.agents.choice_distillation; pre-registration 20);
propose100 / propose10: bound's with `--clone-proposals 4` (the choice also ranks 4 thinned clones, the
clone with fixed dropout masks; EMaQ's best of N; tsrl.agents.reference; pre-registration 22);
ens100 / ens10: bound's with `--critics 5 --actor-value lowest` (IBRL's critic ensemble: the choice and
the TD target take the smallest of 5 heads, the actor climbs the lowest; pre-registration 24);
clones100 / clones10: bound's with `--clones 5` (the reference is the mean action of 5 clones;
pre-registration 26); frontier100 / frontier10: bound's with RFCL's reverse curriculum
(pre-registration 28); nstep100 / nstep10: bound's with `--n-step 3` (pre-registration 32);
measure100 / measure10: bound's with `--clone-episodes 100` (the gate measures the clone on its first
100 episodes; pre-registration 36); lean100 / lean10: bound's with `--utd 1 --bc-steps 2000` (fewer
gradient steps: pre-registration 39); small100 / small10: lean's with `--net-arch 128 128`;
radius100 / radius10: the same with `--reward-scale 1` (pre-registration 10);
igate100 / igate10: that of commits ef4c768-1ca11d0 (pre-registration 6: the gate,
IBRL's choice, the clone measured once); gate100 / gate10:
that of commit 35ff8dc (pre-registration 5: lcb's learner, and the clone acts until the choice is
measured better on the task, tsrl.agents.acting_gate); lcb100 / lcb10: that of commit c09ac4e (pre-registration 4: the
clone trained as BC's and kept as a reference, the actor acting only where the critic's lowest head for
it is above its highest for the clone); ref100 / ref10: that of commits ab08374-a5747a7
(pre-registration 3), fast100 / fast10: that of commits
a6205d2-6840ec2 (pre-registration 2), whose rows are kept; run them at one of those commits. `--probe` writes the row to data/probes.csv instead (a probe
is not a screen: one seed, to find a bug or a cause before the pre-registered runs).
On UR5ePickPlace-v0 the arms carry `-press` (bc100-press, margin100-press: the solver's
demonstrations since pre-registration 9, NEW_DEMOS); its rows without it are of the old ones.
Every evaluation has 100 episodes on the run's fixed unseen seeds. Per run: final = mean of the last
three evaluations; fresh = success of the final policy on 100 fresh seeds; to95 = the env steps from
which the mean of three consecutive evaluations stays at or above 0.95 (curves.sustained_crossing);
min_after = the lowest evaluation after the first 2,500 env steps (the floor target).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import TrainConfig, resume, train
from tsrl.agents.checkpoint import load_policy, usable_checkpoint
from tsrl.agents.config import AgentConfig, DemoConfig
from tsrl.agents.demo_files import save_demos
from tsrl.agents.demonstrators import record_demos
from tsrl.agents.evaluation import Evaluator, fresh_eval_seeds
from tsrl.agents.factory import ALGO_CLASSES
from tsrl.agents.run_folder import CONFIG_FILE, read_progress
from tsrl.experiments.curves import sustained_crossing

HERE = Path(__file__).resolve().parent
RUNS_CSV = HERE / "data" / "runs.csv"
PROBES_CSV = HERE / "data" / "probes.csv"
COLUMNS = (
    "task",
    "arm",
    "seed",
    "budget",
    "evals",
    "final",
    "fresh",
    "to95",
    "min_after",
    "wall_s",
    "commit",
)
EVAL_EPISODES = 100
#: Env-step budgets of the learner arms per task (the issue's targets' budgets).
BUDGETS = {
    "PandaPickPlaceGripper-v0": 10_000,
    "PandaPush-v0": 30_000,
    "PandaStack-v0": 150_000,
    "PandaPegInsert-v0": 150_000,
    "UR5ePickPlace-v0": 12_500,
}
EVAL_FREQ = {"PandaPickPlaceGripper-v0": 1_250, "UR5ePickPlace-v0": 1_250}  # others: 2,500
#: Tasks whose scripted demonstrations changed during the study, and the suffix their arms carry from
#: then on (bc100-press): the suction's solver presses the cup 1.5 cm below the box top (was 4 mm;
#: pre-registration 9). Their rows without it are of the old demonstrations.
NEW_DEMOS = {"UR5ePickPlace-v0": "-press"}
#: The arms this commit runs (the others name the commits that ran them).
ACCEPTED_ARMS = (
    "bc100, bc10, margin100, margin10, radius100, radius10, bound100, bound10, adapt100, adapt10, "
    "reset100, reset10, distill100, distill10, propose100, propose10, ens100, ens10, clones100, clones10, "
    "frontier100, frontier10, nstep100, nstep10, measure100, measure10, lean100, lean10, small100, small10"
)


#: The learner arms built on `bound` (the preset with the return bound), each adding one option.
BOUND_ARMS = (
    "bound",
    "adapt",
    "reset",
    "distill",
    "propose",
    "ens",
    "clones",
    "frontier",
    "nstep",
    "measure",
    "lean",
    "small",
)


def budget(task: str, n: int) -> int:
    """Env steps of a learner arm with `n` demonstrations: BUDGETS, but the gripper pick-and-place with
    10 demonstrations has its target's 60,000."""
    return 60_000 if (task, n) == ("PandaPickPlaceGripper-v0", 10) else BUDGETS[task]


def base_arm(arm: str, task: str) -> str:
    """The arm without its demonstrations' suffix (NEW_DEMOS), which a task with new demonstrations
    requires and others refuse."""
    suffix = NEW_DEMOS.get(task, "")
    if suffix and not arm.endswith(suffix):
        raise SystemExit(f"{task}'s demonstrations changed (pre-registration 9): its arms are {arm}{suffix}")
    if not suffix and "-" in arm:
        raise SystemExit(f"arm {arm!r} on {task}: only {sorted(NEW_DEMOS)} take a demonstrations' suffix")
    return arm.removesuffix(suffix)


def demo_count(arm: str) -> int:
    """The demonstrations an arm learns from: the number its name ends in (bc100 -> 100)."""
    digits = arm.split("-")[0].lstrip("abcdefghijklmnopqrstuvwxyz")
    if not digits.isdigit():
        raise SystemExit(f"arm {arm!r} names no number of demonstrations; accepted: {ACCEPTED_ARMS}")
    return int(digits)


def arm_config(arm: str, task: str, seed: int, demos: Path) -> TrainConfig:
    arm = base_arm(arm, task)
    demo_cfg = DemoConfig(path=str(demos))
    if arm.startswith("bc"):
        agent = AgentConfig(algo="bc", bc_steps=8_000, demos=demo_cfg)
        return TrainConfig(
            env_id=f"tsrl/{task}", seed=seed, eval_freq=2_000, eval_episodes=EVAL_EPISODES,
            checkpoint_freq=4_000, agent=agent,
        )  # fmt: skip
    if arm.startswith(("margin", "radius", *BOUND_ARMS)):
        # radius: the reward at the task's tolerances; margin and radius: the preset of pre-registration 8, before the return bound joined it
        options: dict[str, Any] = {"return_bound": 0.0}
        if arm.startswith("radius"):
            options["reward_scale"] = 1.0
        if arm.startswith(BOUND_ARMS):
            # margin's, with the returns as the critic's lower bound
            options = {"return_bound": 1.0}
        if arm.startswith("reset"):
            # bound's, half of the training episodes started from a demonstration's state
            demo_cfg = dataclasses.replace(demo_cfg, reset_prob=0.5)
        if arm.startswith("frontier"):
            # bound's, with RFCL's reverse curriculum: half of the training episodes from a frontier
            demo_cfg = dataclasses.replace(demo_cfg, reset_prob=0.5, reset_frontier_k=3)
        if arm.startswith("distill"):
            # bound's, with the choice between actor and clone cloned into the actor
            options["distill_choice"] = 1.0
        if arm.startswith("propose"):  # bound's, the choice ranking 4 thinned clones too
            options["clone_proposals"] = 4
        if arm.startswith("clones"):  # bound's, the reference the mean action of 5 clones
            options["clones"] = 5
        if arm.startswith("nstep"):  # bound's, with 3-step targets for the critic
            options["n_step"] = 3
        if arm.startswith("measure"):  # bound's, the gate measuring the clone on 100 episodes
            options["clone_episodes"] = 100
        if arm.startswith(("lean", "small")):  # bound's, fewer gradient steps (and smaller networks)
            options |= {"utd": 1.0, "bc_steps": 2_000}
        if arm.startswith("small"):
            options["net_arch"] = (128, 128)
        if arm.startswith("ens"):  # bound's, with a pessimistic ensemble of 5 critic heads
            options |= {"critics": 5, "actor_value": "lowest"}
        if arm.startswith("adapt"):  # bound's, with the explore noise kept winnable
            options["adaptive_noise"] = True
        agent = AgentConfig(learner="fast", demos=demo_cfg, **options)
        return TrainConfig(
            env_id=f"tsrl/{task}", seed=seed, total_timesteps=budget(task, demo_count(arm)),
            eval_freq=EVAL_FREQ.get(task, 2_500),
            eval_episodes=EVAL_EPISODES, checkpoint_freq=5_000, agent=agent,
        )  # fmt: skip
    old_designs = {
        "fast": "a6205d2-6840ec2", "ref": "ab08374-a5747a7", "lcb": "c09ac4e", "gate": "35ff8dc",
        "igate": "ef4c768-1ca11d0",
    }  # fmt: skip
    for old, commits in old_designs.items():
        if arm.startswith(old):
            raise SystemExit(f"arm {arm!r} is --learner fast of commits {commits}: run it at one of them")
    raise SystemExit(f"unknown arm {arm!r}; accepted: {ACCEPTED_ARMS}")


def demo_file(out: Path, task: str, n: int) -> Path:
    path = out / "demos" / f"{task}-{n}{NEW_DEMOS.get(task, '')}.npz"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        save_demos(record_demos(f"tsrl/{task}", n, seed=0), path)
    return path


def fresh_success(run_dir: Path, cfg: TrainConfig) -> float:
    checkpoint = usable_checkpoint(run_dir, cfg.agent.normalize, for_training=False)
    assert checkpoint is not None
    model, normalizer = load_policy(checkpoint, ALGO_CLASSES[cfg.agent.algo])
    evaluator = Evaluator(cfg, fresh_eval_seeds(cfg.seed, EVAL_EPISODES))
    try:
        return evaluator.evaluate(model, normalizer).success_rate
    finally:
        evaluator.close()


def metrics(run_dir: Path, cfg: TrainConfig) -> dict[str, Any]:
    rows = read_progress(run_dir)
    bc = cfg.agent.algo == "bc"
    clock = [r["gradient_steps" if bc else "env_steps"] for r in rows]
    success = [r["eval_success_rate"] for r in rows]
    after = [s for c, s in zip(clock, success, strict=True) if c >= (1 if bc else 2_500)]
    return {
        "budget": int(clock[-1]),
        "evals": len(rows),
        "final": round(float(np.mean(success[-3:])), 4),
        "fresh": fresh_success(run_dir, cfg),
        "to95": "" if bc else sustained_crossing(clock, success, 0.95),
        "min_after": round(min(after), 4) if after else math.nan,
        "wall_s": round(rows[-1]["wall_time_s"], 1),
    }


def commit() -> str:
    return subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], check=False, capture_output=True, text=True, cwd=HERE
    ).stdout.strip()


def train_arm(
    arm: str,
    task: str,
    seeds: list[int],
    out: Path,
    probe: bool = False,
    change: Callable[[AgentConfig], AgentConfig] | None = None,
) -> None:
    """Trains `arm` on `task` per seed and appends its row; `change`, where given, alters each run's
    agent configuration (a probe's variant of the arm)."""
    arm_config(arm, task, seeds[0], Path())  # an unknown or old arm is refused before any recording
    demos = demo_file(out, task, demo_count(arm))
    done = set() if probe else {(r["task"], r["arm"], r["seed"]) for r in read_rows()}
    for seed in seeds:
        if (task, arm, str(seed)) in done:
            continue
        cfg = arm_config(arm, task, seed, demos)
        if change is not None:
            cfg = dataclasses.replace(cfg, agent=change(cfg.agent))
        parent = out / arm / task
        run_dir = parent / cfg.run_name
        if (run_dir / CONFIG_FILE).is_file():
            resume(run_dir, progress_bar=False)  # a killed run goes on from its checkpoint
        else:
            run_dir = train(cfg, parent, progress_bar=False)
        row = {"task": task, "arm": arm, "seed": seed, **metrics(run_dir, cfg), "commit": commit()}
        append_row(row, PROBES_CSV if probe else RUNS_CSV)
        print(row, flush=True)


def bc_probe(arm: str, task: str, seed: int, demos: Path, out: Path) -> Path:
    """Pre-registration 1's BC on the demonstration file `demos` (a probe's own), trained under
    out/arm/task; its row goes to data/probes.csv as `arm`. Returns the run folder."""
    cfg = arm_config("bc100", task, seed, demos)  # the bc arm's configuration; the file is the probe's
    run_dir = train(cfg, out / arm / task, progress_bar=False)
    row = {"task": task, "arm": arm, "seed": seed, **metrics(run_dir, cfg), "commit": commit()}
    append_row(row, PROBES_CSV)
    print(row, flush=True)
    return run_dir


#: Probe rows that a pre-registration counts as rows of its screen: (task, arm, seed) -> pre-registration.
COUNTED_PROBES = {("PandaPickPlaceGripper-v0", "bound100", "0"): "18"}


def read_rows() -> list[dict[str, str]]:
    """The screens' rows: data/runs.csv and the probe rows of COUNTED_PROBES."""
    rows = _read_csv(RUNS_CSV)
    return rows + [r for r in _read_csv(PROBES_CSV) if (r["task"], r["arm"], r["seed"]) in COUNTED_PROBES]


def _read_csv(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def append_row(row: dict[str, Any], path: Path) -> None:
    new = not path.is_file()
    with open(path, "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=COLUMNS)
        if new:
            writer.writeheader()
        writer.writerow(row)


def _per(rs: list[dict[str, str]], key: str) -> str:
    return ", ".join(f"{float(r[key]):.2f}" if r[key] not in ("", "nan") else "-" for r in rs)


def table() -> None:
    rows = read_rows()
    groups: dict[tuple[str, str], list[dict[str, str]]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["arm"]), []).append(r)
    print(
        "| task | arm | seeds | budget | final (mean of last 3), per seed | fresh 100, per seed | "
        "to 95 % (sustained), per seed | lowest eval after 2,500 |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for (task, arm), rs in sorted(groups.items()):
        rs.sort(key=lambda r: int(r["seed"]))
        to95 = ", ".join(f"{float(r['to95']):,.0f}" if r["to95"] not in ("", "nan") else "-" for r in rs)
        print(
            f"| {task} | {arm} | {len(rs)} | {rs[0]['budget']} | {_per(rs, 'final')} | {_per(rs, 'fresh')} | {to95} | "
            f"{min(float(r['min_after']) for r in rs):.2f} |"
        )


#: The issue's targets: every seed at 95 % (sustained) within these env steps, per (task, demonstrations).
TARGETS = {
    ("PandaPickPlaceGripper-v0", 100): 5_000,
    ("PandaPickPlaceGripper-v0", 10): 60_000,
    ("PandaPush-v0", 100): 30_000,
    ("PandaStack-v0", 100): 150_000,
    ("PandaPegInsert-v0", 100): 150_000,
    ("UR5ePickPlace-v0", 100): 12_500,
}


#: The learner arms and the pre-registration whose rules they are judged by (README).
LEARNER_ARMS = {
    "fast": "2",
    "ref": "3",
    "lcb": "4",
    "gate": "5",
    "igate": "6",
    "margin": "8",
    "bound": "14-15, 18, 21, 23",
    "clones": "27",
}
#: Learner arms on a task's new demonstrations (NEW_DEMOS), with their pre-registration.
NEW_DEMO_ARMS = {"margin": "9", "radius": "10", "bound": "16"}


def verdicts() -> None:
    """The pre-registered rules (README, pre-registrations 2-10) for each task and learner arm."""
    rows = read_rows()
    print(
        "| task | demos | learner arm (pre-registration) | BC floor | learner seeds | lowest eval after 2,500 | "
        "floor held | seeds at 95 % within target | target |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for (task, n), target in TARGETS.items():
        for arm, pre in LEARNER_ARMS.items():
            _verdict(rows, task, n, target, f"{arm}{n}", pre)
        if task in NEW_DEMOS:
            for arm, pre in NEW_DEMO_ARMS.items():
                _verdict(rows, task, n, target, f"{arm}{n}{NEW_DEMOS[task]}", pre, NEW_DEMOS[task])


#: How far below BC's mean final an evaluation may lie (the issue's floor rule).
FLOOR_MARGIN = 0.05


def floor_line(rows: list[dict[str, str]], task: str, n: int, suffix: str = "") -> float:
    """The floor rule's line on `task`: BC's mean final on the same `n` demonstrations (arm
    bc{n}{suffix}) minus FLOOR_MARGIN; NaN without BC rows."""
    bc = [float(r["final"]) for r in rows if (r["task"], r["arm"]) == (task, f"bc{n}{suffix}")]
    return float(np.mean(bc)) - FLOOR_MARGIN if bc else math.nan


def _verdict(
    rows: list[dict[str, str]], task: str, n: int, target: int, arm: str, pre: str, suffix: str = ""
) -> None:
    bc = [float(r["final"]) for r in rows if r["task"] == task and r["arm"] == f"bc{n}{suffix}"]
    fast = [r for r in rows if r["task"] == task and r["arm"] == arm]
    if bc and fast:
        floor = float(np.mean(bc))
        lowest, within = _lowest_and_within(fast, target)
        # every seed must get there: one finished seed that does not decides "missed"
        met = "missed" if within < len(fast) else "met" if len(fast) == 5 else "not decided"
        print(
            f"| {task} | {n} | {arm} ({pre}) | {floor:.2f} | {len(fast)} | {lowest:.2f} | "
            f"{'yes' if lowest >= floor - FLOOR_MARGIN else 'no'} | {within} of {len(fast)} within {target:,} | {met} |"
        )


#: The preset's arm per task in the summary: `--learner fast` since pre-registration 17 (the suction's
#: on its new demonstrations, NEW_DEMOS).
PRESET_ARM = "bound"
SUMMARY_BEGIN = (
    "<!-- learner-from-demos summary: `python studies/learner-from-demos/run.py summary`; do not edit -->"
)
SUMMARY_END = "<!-- learner-from-demos summary: end -->"


#: The summary's rows beyond TARGETS: the 10-demonstration arms the issue asks reported beside BC's.
REPORTED_WITHOUT_TARGET = (("PandaPush-v0", 10), ("PandaStack-v0", 10), ("PandaPegInsert-v0", 10))


def summary(rows: list[dict[str, str]] | None = None) -> list[str]:
    """The issue's benchmark table (docs/results.md), one line per task and number of demonstrations:
    BC's finals, the preset's finals per seed, its seeds at 95 % within the target, the floor rule."""
    rows = read_rows() if rows is None else rows
    lines = [
        (
            "| task | demos | BC: final (5 seeds) | `--learner fast`: final per seed | seeds | at 95 % (sustained) "
            "within the target | floor held: lowest evaluation after 2,500 (line) |"
        ),
        "| --- | ---: | --- | --- | ---: | --- | --- |",
    ]
    reported: list[tuple[tuple[str, int], int | None]] = [*TARGETS.items()]
    reported += [(key, None) for key in REPORTED_WITHOUT_TARGET]
    for (task, n), target in reported:
        suffix = NEW_DEMOS.get(task, "")
        bc = sorted(float(r["final"]) for r in rows if (r["task"], r["arm"]) == (task, f"bc{n}{suffix}"))
        fast = sorted(
            (r for r in rows if (r["task"], r["arm"]) == (task, f"{PRESET_ARM}{n}{suffix}")),
            key=lambda r: int(r["seed"]),
        )
        bc_cell = f"{bc[0]:.2f}-{bc[-1]:.2f}" if bc else "-"
        if not fast:
            lines.append(f"| {task} | {n} | {bc_cell} | not run | 0 of 5 | - | - |")
            continue
        lowest, within = _lowest_and_within(fast, target or 0)
        reached = f"{within} of {len(fast)} within {target:,}" if target else "no target"
        line = floor_line(rows, task, n, suffix)
        held = "yes" if lowest >= line else "no"
        lines.append(
            f"| {task} | {n} | {bc_cell} | {_per(fast, 'final')} | {len(fast)} of 5 | {reached} | "
            f"{held}: {lowest:.2f} ({line:.3f}) |"
        )
    return lines


def _lowest_and_within(fast: list[dict[str, str]], target: int) -> tuple[float, int]:
    """The learner rows' lowest evaluation after 2,500 env steps (the floor rule reads it) and how many
    of them hold 95 % (sustained) within `target` env steps."""
    lowest = min(float(r["min_after"]) for r in fast)
    within = sum(r["to95"] not in ("", "nan") and float(r["to95"]) <= target for r in fast)
    return lowest, within


def one_run_parser(description: str) -> argparse.ArgumentParser:
    """The arguments of the scripts that train one run of an arm (time_to_target.py, probe_average.py):
    ARM TASK --seed S --out DIR."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("arm")
    parser.add_argument("task", choices=sorted(BUDGETS))
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--out", type=Path, required=True)
    return parser


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train")
    t.add_argument("arm")
    t.add_argument("task", choices=sorted(BUDGETS))
    t.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    t.add_argument("--out", type=Path, default=Path("results/learner-from-demos"))
    t.add_argument("--probe", action="store_true", help="write the row to data/probes.csv (not a screen)")
    sub.add_parser("table")
    sub.add_parser("summary", help="the issue's benchmark table of docs/results.md")
    args = parser.parse_args()
    if args.command == "train":
        train_arm(args.arm, args.task, args.seeds, args.out, args.probe)
    elif args.command == "summary":
        print("\n".join(summary()))
    else:
        table()
        print()
        verdicts()


if __name__ == "__main__":
    sys.exit(main())
