"""Environment step speed: tsrl/UR5eReach-v0 (fs2, taskspace) against Gymnasium-Robotics FetchReach-v4.

Both run random actions, measured in one process with episodes alternating, and our step is
broken down into physics (the 20 mj_step substeps), task maps (one evaluation of every map the step
needs), IK and the rest (action checks, observation dicts, reward, Python overhead). A last table
gives every built-in task's steps per second (its default observation and action), alternating too.

    python benchmarks/env_step.py [--rounds 5] [--episodes 10] [--task-rounds 3] [--task-episodes 4]
                                  [--save [NAME]]

--save writes every step's time (microseconds, to the nanosecond) to docs/results/benchmarks/NAME/
(default env-step: the two environments' steps and the breakdown's) and NAME-tasks/ (every task's
steps), with meta.json (benchmarks/record.py); `table` and `tasks_table` render docs/envs.md's
tables from them.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

if TYPE_CHECKING:  # the measuring functions import these; the table renderers need none of them
    import gymnasium as gym

DOC = "docs/envs.md"
BREAKDOWN_CSV = "breakdown.csv"
TASKS_CSV = "tasks.csv"
PARTS = ("physics", "task maps", "IK", "whole step")  # measured; "rest" = whole step - the others
EPISODE_STEPS = 50  # the compared reach tasks' episode length


def episode_step_times(env: gym.Env, seed: int) -> list[float]:
    """Seconds of each env.step (wrappers of gym.make included) over one episode of random actions."""
    env.action_space.seed(seed)
    env.reset(seed=seed)
    durations = []
    truncated = terminated = False
    while not (truncated or terminated):
        action = env.action_space.sample()
        t0 = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(action)
        durations.append(time.perf_counter() - t0)
    return durations


def breakdown(env: gym.Env, steps: int, seed: int) -> list[dict[str, float]]:
    """Per step: seconds of each part of our step (PARTS), each timed on the state the step sees."""
    import mujoco

    u: Any = env.unwrapped  # the TaskEnv under the wrappers
    scratch = mujoco.MjData(u.model)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    rows = []
    for _ in range(steps):
        action = env.action_space.sample()
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        t0 = time.perf_counter()
        u.interface.command(a, u.data.qpos[u.bound_robot.qpos], u.data)  # action map, IK, tool
        ik = time.perf_counter() - t0
        mujoco.mj_copyData(scratch, u.model, u.data)
        t0 = time.perf_counter()
        for _ in range(u.n_substeps):
            mujoco.mj_step(u.model, scratch)
        physics = time.perf_counter() - t0
        t0 = time.perf_counter()
        u.plan._maps.in_place(u.model, u.data)  # as the step evaluates them: no copies
        maps = time.perf_counter() - t0
        t0 = time.perf_counter()
        _, _, _, truncated, _ = env.step(action)
        whole = time.perf_counter() - t0
        rows.append({"physics": physics, "task maps": maps, "IK": ik, "whole step": whole})
        if truncated:
            env.reset()
    return rows


#: The compared environments: name in the tables -> (gym id, make kwargs).
ENVS: dict[str, tuple[str, dict[str, Any]]] = {
    "tsrl/UR5eReach-v0 (fs2, taskspace)": ("tsrl/UR5eReach-v0", {"obs": "fs2", "action": "taskspace"}),
    "FetchReach-v4": ("FetchReach-v4", {}),
}


def make_env(name: str) -> gym.Env:
    """The environment called `name` in ENVS (FetchReach-v4 with its mujoco-4 patch registered)."""
    import gymnasium as gym
    from fetch_compat import register_fetch_envs

    import tsrl  # noqa: F401  (registers the tsrl environments)

    register_fetch_envs()
    env_id, kwargs = ENVS[name]
    return gym.make(env_id, **kwargs)


def us(seconds: float) -> float:
    """Microseconds, to the nanosecond (perf_counter's resolution)."""
    return round(seconds * 1e6, 3)


def measure_compare(rounds: int, episodes: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(one row per step of the two ENVS: env, round, episode, us; one row per breakdown step: the
    PARTS in us). Episodes alternate one by one, so a change in the machine's speed hits both alike."""
    envs = {name: make_env(name) for name in ENVS}
    rows: list[dict[str, Any]] = []
    for r in range(rounds):
        for e in range(episodes):
            for name, env in envs.items():
                for t in episode_step_times(env, seed=100 * r + e):
                    rows.append({"env": name, "round": r, "episode": e, "us": us(t)})
    ours = next(iter(ENVS))
    parts = breakdown(envs[ours], steps=episodes * EPISODE_STEPS, seed=7)
    return rows, [{k: us(v) for k, v in p.items()} for p in parts]


def measure_tasks(rounds: int, episodes: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(one row per step of every built-in task, its default observation and action: task, round,
    episode, us; one row per task: task, observation, action dim), the tasks alternating episode by
    episode."""
    import gymnasium as gym

    import tsrl

    tasks: dict[str, Any] = {env_id: gym.make(env_id) for env_id in tsrl.ENV_IDS}
    rows: list[dict[str, Any]] = []
    for r in range(rounds):
        for e in range(episodes):
            for env_id, env in tasks.items():
                for t in episode_step_times(env, seed=100 * r + e):
                    rows.append({"task": env_id, "round": r, "episode": e, "us": us(t)})
    described = [
        {
            "task": env_id,
            "observation": env.unwrapped.task.observation,
            "action_dim": env.action_space.shape[0],
        }
        for env_id, env in tasks.items()
    ]
    return rows, described


def render(steps: list[dict[str, Any]], parts: list[dict[str, Any]]) -> list[str]:
    """docs/envs.md's speed tables (markdown lines) from `measure_compare`'s rows (or their CSV strings)."""
    names = list(dict.fromkeys(r["env"] for r in steps))
    ours, fetch = names
    times = {name: [float(r["us"]) for r in steps if r["env"] == name] for name in names}
    rate = {name: 1e6 / statistics.median(v) for name, v in times.items()}
    rounds = list(dict.fromkeys(r["round"] for r in steps))

    def round_median(name: str, rnd: str) -> float:
        return statistics.median(float(r["us"]) for r in steps if r["env"] == name and r["round"] == rnd)

    round_ratios = [round_median(fetch, rnd) / round_median(ours, rnd) for rnd in rounds]
    episodes = len({(r["round"], r["episode"]) for r in steps if r["env"] == ours})
    heading = (
        f"Steps per second (1 / median step time), random actions, {len(rounds)} rounds of "
        f"{episodes // len(rounds)} episodes each, the two environments alternating episode by episode:"
    )
    ratio = (
        f"Ratio tsrl / FetchReach-v4: **{rate[ours] / rate[fetch]:.2f}x** (target >= 4x); per round "
        f"{min(round_ratios):.2f}x to {max(round_ratios):.2f}x."
    )
    lines = [
        heading,
        "",
        "| environment | steps/s |",
        "| --- | ---: |",
    ]
    lines += [f"| {name} | {v:,.0f} |" for name, v in rate.items()]
    lines += ["", ratio, ""]
    median = {k: statistics.median(float(p[k]) for p in parts) for k in PARTS}
    median["rest"] = median["whole step"] - median["physics"] - median["task maps"] - median["IK"]
    whole = median["whole step"]
    lines += [
        f"Breakdown of one tsrl/UR5eReach-v0 step (median over {len(parts)} steps):",
        "",
        "| part of our step | median µs | share |",
        "| --- | ---: | ---: |",
    ]
    labels = {"physics": "physics (20 `mj_step`)"}
    for k in ("physics", "task maps", "IK", "rest", "whole step"):
        lines.append(f"| {labels.get(k, k)} | {median[k]:.1f} | {median[k] / whole:.0%} |")
    lines += ["", f"Whole step / physics alone: **{whole / median['physics']:.2f}x** (target <= 2x)."]
    return lines


def render_tasks(steps: list[dict[str, Any]], described: list[dict[str, Any]]) -> list[str]:
    """docs/envs.md's every-task table (markdown lines) from `measure_tasks`' rows (or their CSV strings)."""
    rounds = len({r["round"] for r in steps})
    episodes = len({(r["round"], r["episode"]) for r in steps}) // rounds
    lines = [
        f"{rounds} rounds of {episodes} episodes per task, the tasks alternating episode by episode:",
        "",
        "| task | observation | action dim | steps/s |",
        "| --- | --- | ---: | ---: |",
    ]
    for d in described:
        rate = 1e6 / statistics.median(float(r["us"]) for r in steps if r["task"] == d["task"])
        lines.append(f"| {d['task']} | {d['observation']} | {d['action_dim']} | {rate:,.0f} |")
    return lines


def table(data_dir: Path) -> list[str]:
    """The speed tables from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV), read_rows(data_dir / BREAKDOWN_CSV))


def tasks_table(data_dir: Path) -> list[str]:
    """The every-task table from the data `--save` wrote to `data_dir` (NAME-tasks)."""
    return render_tasks(read_rows(data_dir / DATA_CSV), read_rows(data_dir / TASKS_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="alternating measurement rounds")
    parser.add_argument("--episodes", type=int, default=10, help="50-step episodes per env per round")
    parser.add_argument("--task-rounds", type=int, default=3, help="rounds of the every-task table")
    parser.add_argument("--task-episodes", type=int, default=4, help="episodes per task per round")
    add_save_argument(parser, "env-step")
    args = parser.parse_args()

    with Measurement(args.save, __file__, "table", DOC) as out:
        steps, parts = measure_compare(args.rounds, args.episodes)
        if out is not None:
            write_rows(out / DATA_CSV, steps)
            write_rows(out / BREAKDOWN_CSV, parts)
    print("\n" + "\n".join(render(steps, parts)) + "\n")
    tasks_name = None if args.save is None else f"{args.save}-tasks"
    with Measurement(tasks_name, __file__, "tasks_table", DOC) as out:
        task_steps, described = measure_tasks(args.task_rounds, args.task_episodes)
        if out is not None:
            write_rows(out / DATA_CSV, task_steps)
            write_rows(out / TASKS_CSV, described)
    print("Every built-in task, its default observation and action, random actions:\n")
    print("\n".join(render_tasks(task_steps, described)))


if __name__ == "__main__":
    main()
