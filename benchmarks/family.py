"""The manipulation family's learning benchmark: DDPG + HER with 100 scripted demonstrations per task
(the paper's agent and tsrl's Q-filtered BC loss, each task's own observation and action); prints, per
task, env steps and training time to 50/90/95 % evaluation success per seed and whether every seed
reached 95 % within the task's target budget.

    python benchmarks/family.py                      # every task, 5 seeds, its target budget
    python benchmarks/family.py --tasks PandaPush-v0 --seeds 0 1 --jobs 2
    python benchmarks/family.py --tasks PandaPush-v0 --learner fast   # issue 27's preset as the remedy
    python benchmarks/family.py --tasks PandaPush-v0 --learner fast --action-l2 1   # a penalty on actions
    python benchmarks/family.py --tasks PandaPush-v0 --learner fast --algo tqc      # a stochastic actor
    python benchmarks/family.py --tasks PandaPush-v0 --learner fast --utd 4         # more gradient steps
    python benchmarks/family.py --tasks PandaStack-v0 --demos-reset-prob 0.5 --demos-reset-curriculum-steps 100000
                                                     # resets to demonstration states, a reverse curriculum
    python benchmarks/family.py --tasks task_files/panda_push_half_step.toml --learner fast
                                                     # a task file: a family task's variant (its `solver`)
    python benchmarks/learning.py family ...         # the same

| task | target (env steps, every seed at 95 %) | best anchor known |
| --- | ---: | --- |
| push | 30,000 | Fetch push, DDPG + HER: 0.95 at ~700,000 without demonstrations |
| gripper pick-and-place | 60,000 | Fetch pick-and-place + 100 demos: ~0.9 at ~400,000 |
| stack | 150,000 | panda-gym stack, TQC + HER: mostly fails at 1,000,000 |
| peg insertion (2 mm) | 150,000 | ManiSkill PegInsertionSide: solved from sparse reward by a reverse curriculum |

A task file in --tasks (a path ending in .toml) is a variant of the family task its `solver` key names
(another action map, say): it runs with that task's budget, evaluation period and scripted solver.

Runs are ordinary run folders under --out-dir (default results/benchmarks/family/<task>/): a finished
one is reused, an interrupted one resumed. The demonstrations are recorded once per task (seed 0, the
task's scripted solver, successful episodes only) into --out-dir/demos/.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")

from learning import in_parallel, train_or_resume
from learning_tables import (
    FAMILY_TASKS,
    THRESHOLDS,
    every_seed_within,
    family_label,
    family_variant,
    first_reaching,
    group_table,
    read_progress_csv,
    save_runs,
)
from record import Measurement, add_save_argument

from tsrl.agents import AgentConfig, TrainConfig
from tsrl.agents.config import ALGOS, TASK_ACTION, TASK_FILE_SUFFIX, Algo, DemoConfig, Learner
from tsrl.exceptions import InvalidConfig

EVAL_EPISODES = 100
DEMO_EPISODES = 100
#: Resets to demonstration states: (probability, reverse-curriculum env steps, reverse-curriculum
#: success rate: DemoConfig's reset_prob, reset_curriculum_steps, reset_curriculum_success), or None.
DemoResets = tuple[float, int, float] | None


def is_task_file(task: str) -> bool:
    """Whether `task` (an entry of --tasks) is a task file rather than a family task's name."""
    return task.endswith(TASK_FILE_SUFFIX)


def env_id(task: str) -> str:
    """The environment id of an entry of --tasks: tsrl/<name>, or the task file's path."""
    return task if is_task_file(task) else f"tsrl/{task}"


def task_label(task: str) -> str:
    """An entry of --tasks as run folders and demonstration files name it: the name, or the file's stem."""
    return Path(task).stem if is_task_file(task) else task


def family_task(task: str) -> str:
    """The family task whose budget and solver apply to an entry of --tasks: a name of FAMILY_TASKS itself, or
    a task file's `solver` (InvalidConfig, one line, where that is not a family task)."""
    from tsrl.envs import load_task

    if not is_task_file(task):
        return task
    solver = load_task(task).solver
    if solver not in FAMILY_TASKS:
        raise InvalidConfig(
            f"{task}: solver = {solver!r}; a family variant needs the family task it varies, accepted: "
            f"{', '.join(FAMILY_TASKS)}"
        )
    return solver


def record(task: str, out_dir: Path, episodes: int = DEMO_EPISODES) -> Path:
    """The task's (a family task's name or a task file's) `episodes` successful scripted
    demonstrations in its own observation and action, recorded once."""
    from tsrl.agents.demo_files import save_demos, summary_line
    from tsrl.agents.demonstrators import record_demos
    from tsrl.envs import load_task

    path = out_dir / "demos" / f"{task_label(task)}-scripted-{episodes}.npz"
    if not path.is_file():
        demos = record_demos(env_id(task), episodes, obs=load_task(task).observation, seed=0)
        print(summary_line(demos, save_demos(demos, path)), flush=True)
    return path


def configs(
    task: str,
    seeds: list[int],
    total: int,
    eval_freq: int,
    demos: Path,
    learner: Learner = "paper",
    resets: DemoResets = None,
    action_l2: float = 0.0,
    algo: Algo = "ddpg",
    utd: float | None = None,
) -> list[TrainConfig]:
    """The task's runs: the agent of `learner` (paper: today's default; fast: issue 27's preset, whose
    symmetric sampling is a remedy the issue names) with the demonstrations, the task's own
    observation and action; `resets` (probability, curriculum env steps, curriculum success rate):
    episodes started from demonstration states, the other remedy (Nair et al.; a reverse curriculum
    paced by env steps where they are > 0, by success as RFCL's where the rate is > 0), None: the
    learner's; `action_l2` > 0: a penalty on the actor's squared actions (AgentConfig.action_l2);
    `algo`: the off-policy algorithm under HER (the paper's DDPG; SAC and TQC: a stochastic actor);
    `utd`: gradient steps per env step (AgentConfig.utd), None: the learner's."""
    from tsrl.envs import load_task

    prob, steps, success = resets if resets is not None else (None, 0, 0.0)
    demo_config = DemoConfig(
        path=str(demos), reset_prob=prob, reset_curriculum_steps=steps, reset_curriculum_success=success
    )
    agent = AgentConfig(algo=algo, learner=learner, demos=demo_config, action_l2=action_l2, utd=utd)
    return [
        TrainConfig(
            env_id=env_id(task),
            obs=load_task(task).observation,
            action=TASK_ACTION,
            seed=s,
            agent=agent,
            total_timesteps=total,
            eval_freq=eval_freq,
            eval_episodes=EVAL_EPISODES,
        )
        for s in seeds
    ]


def run_parent(task: str, demos: int, resets: DemoResets, utd: float | None = None) -> str:
    """The folder of a task's runs under --out-dir: one per variant, since a run's name does not say
    its demonstration count, resets or update-to-data ratio (a finished run found there is reused)."""
    name = task_label(task) + ("" if demos == DEMO_EPISODES else f"-demos-{demos}")
    name += "" if utd is None else f"-utd-{utd:g}"
    if resets is not None:
        name += f"-resets-{resets[0]:g}" + (f"-curriculum-{resets[1]}" if resets[1] else "")
        name += f"-paced-{resets[2]:g}" if resets[2] else ""
    return name


def run_one(args: tuple[TrainConfig, Path]) -> Path:
    """Trains (or resumes, or reuses) one run in <parent>/<run name>."""
    return train_or_resume(*args)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--tasks",
        nargs="+",
        default=list(FAMILY_TASKS),
        help=f"family tasks ({', '.join(FAMILY_TASKS)}; default: all) or task files (PATH.toml) whose `solver` "
        "is one of them",
    )
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument(
        "--total-timesteps", type=int, default=None, help="per run (default: the task's target)"
    )
    parser.add_argument(
        "--jobs", type=int, default=1, help="runs in parallel (timings: no more than free cores)"
    )
    parser.add_argument(
        "--learner", choices=("paper", "fast"), default="paper", help="the agent preset (default: paper)"
    )
    parser.add_argument(
        "--action-l2",
        type=float,
        default=0.0,
        help="weight of a penalty on the actor's squared actions (OpenAI baselines' HER action_l2, 1.0 "
        "on Fetch; a remedy for reached-then-lost); default 0, none",
    )
    parser.add_argument(
        "--algo",
        choices=ALGOS,
        default="ddpg",
        help="the off-policy algorithm under HER (default: the paper's ddpg; sac, tqc: a stochastic actor)",
    )
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/family"))
    parser.add_argument(
        "--demos",
        type=int,
        default=DEMO_EPISODES,
        help=f"scripted demonstrations per task (default {DEMO_EPISODES}; more: issue 24's first remedy)",
    )
    parser.add_argument(
        "--demos-reset-prob",
        type=float,
        default=None,
        help="episodes started from a demonstration's state with this probability (issue 24's "
        "reset remedy; default: the learner's)",
    )
    parser.add_argument(
        "--demos-reset-curriculum-steps",
        type=int,
        default=0,
        help="with --demos-reset-prob: the restored step drawn from a window at the demonstration's "
        "end that grows to the whole episode over this many env steps (a reverse curriculum, RFCL)",
    )
    parser.add_argument(
        "--demos-reset-curriculum-success",
        type=float,
        default=0.0,
        help="with --demos-reset-prob: a reverse curriculum paced by success instead (the window widens "
        "by a tenth of the demonstration when the last 20 demonstration-started episodes succeed at "
        "this rate; RFCL's advance on success)",
    )
    parser.add_argument(
        "--utd",
        type=float,
        default=None,
        help="gradient steps per env step (default: the learner's: paper 40 per two episodes, fast 2)",
    )
    add_save_argument(parser, "family")
    args = parser.parse_args(argv)
    if args.demos < 1:
        parser.error(f"--demos must be >= 1; got {args.demos}")
    if args.utd is not None and not (math.isfinite(args.utd) and args.utd > 0):
        parser.error(f"--utd must be a finite number > 0 (gradient steps per env step); got {args.utd}")
    for flag in ("demos_reset_curriculum_steps", "demos_reset_curriculum_success"):
        if getattr(args, flag) and args.demos_reset_prob is None:
            parser.error(
                f"--{flag.replace('_', '-')} {getattr(args, flag)} needs --demos-reset-prob (a reset "
                "curriculum restores demonstration states); accepted: --demos-reset-prob P in (0, 1]"
            )
    resets = (
        None
        if args.demos_reset_prob is None
        else (args.demos_reset_prob, args.demos_reset_curriculum_steps, args.demos_reset_curriculum_success)
    )
    for task in args.tasks:
        if not is_task_file(task) and task not in FAMILY_TASKS:
            parser.error(
                f"--tasks: {task!r} is not a family task; accepted: {', '.join(FAMILY_TASKS)}, or a PATH.toml"
            )
        try:
            family_task(task)
        except InvalidConfig as err:
            parser.error(str(err))
    work, work_tasks = [], []  # each run, and the --tasks entry it belongs to
    for task in args.tasks:
        target, eval_freq = FAMILY_TASKS[family_task(task)]
        demos = record(task, args.out_dir, args.demos)
        total = args.total_timesteps or target
        cfgs = configs(
            task,
            args.seeds,
            total,
            eval_freq,
            demos,
            args.learner,
            resets,
            args.action_l2,
            args.algo,
            args.utd,
        )
        parent = args.out_dir / run_parent(task, args.demos, resets, args.utd)
        work += [(cfg, parent) for cfg in cfgs]
        work_tasks += [task] * len(cfgs)
    print(
        f"{len(work)} runs: {', '.join(args.tasks)}; seeds {args.seeds}; learner {args.learner}; "
        f"algo {args.algo}",
        flush=True,
    )
    table = "benchmarks/learning_tables.py:table_family"
    with Measurement(args.save, __file__, table, "studies/manipulation-family/README.md") as out:
        done = in_parallel(run_one, work, args.jobs)
        if out is not None:
            save_runs(done, out)
    lines = [
        "| task | target | env steps to 95 % per seed | every seed within the target |",
        "| --- | ---: | --- | --- |",
    ]
    for task in args.tasks:
        runs = [(cfg, d) for (cfg, _), d, t in zip(work, done, work_tasks, strict=True) if t == task]
        run_dirs = [d for _, d in runs]
        variant = family_variant(runs[0][0].to_dict())
        label = family_label(runs[0][0].env_id) + (f" ({', '.join(variant)})" if variant else "")  # as saved
        print("\n".join(["", *group_table(label, run_dirs, train_time=True)]))
        target = FAMILY_TASKS[family_task(task)][0]
        steps = [first_reaching(read_progress_csv(d), THRESHOLDS[-1], True)[0] for d in run_dirs]
        cells = ", ".join("not reached" if math.isnan(s) else f"{s:,.0f}" for s in steps)
        met = every_seed_within(steps, target)
        lines.append(f"| {task} | {target:,} | {cells} | {'yes' if met else 'no'} |")
    print("\n".join(["", *lines]))


if __name__ == "__main__":
    main()
