"""Environment step speed: tsrl/UR5eReach-v0 (fs2, taskspace) against Gymnasium-Robotics FetchReach-v4.

Both run random actions, measured in one process with episodes alternating, and our step is
broken down into physics (the 20 mj_step substeps), task maps (one evaluation of every map the step
needs), IK and the rest (action checks, observation dicts, reward, Python overhead). A last table
gives every built-in task's steps per second (its default observation and action), alternating too.

    python benchmarks/env_step.py [--rounds 5] [--episodes 10]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium as gym
import mujoco
import numpy as np
from fetch_compat import register_fetch_envs

import tsrl


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


def breakdown(env: gym.Env, steps: int, seed: int) -> dict[str, float]:
    """Microseconds per step of each part of our step, each timed on the state the step sees."""
    u = env.unwrapped
    scratch = mujoco.MjData(u.model)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    parts = {"whole step": [], "physics": [], "task maps": [], "IK": []}
    for _ in range(steps):
        action = env.action_space.sample()
        a = np.clip(np.asarray(action, dtype=np.float64), -1.0, 1.0)
        t0 = time.perf_counter()
        u._joint_targets(a)
        parts["IK"].append(time.perf_counter() - t0)
        mujoco.mj_copyData(scratch, u.model, u.data)
        t0 = time.perf_counter()
        for _ in range(u.n_substeps):
            mujoco.mj_step(u.model, scratch)
        parts["physics"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        u.plan._maps.in_place(u.model, u.data)  # as the step evaluates them: no copies
        parts["task maps"].append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        _, _, _, truncated, _ = env.step(action)
        parts["whole step"].append(time.perf_counter() - t0)
        if truncated:
            env.reset()
    us = {k: 1e6 * statistics.median(v) for k, v in parts.items()}
    us["rest"] = us["whole step"] - us["physics"] - us["task maps"] - us["IK"]
    return us


#: The compared environments: name in the tables -> (gym id, make kwargs).
ENVS = {
    "tsrl/UR5eReach-v0 (fs2, taskspace)": ("tsrl/UR5eReach-v0", {"obs": "fs2", "action": "taskspace"}),
    "FetchReach-v4": ("FetchReach-v4", {}),
}


def make_env(name: str) -> gym.Env:
    """The environment called `name` in ENVS (FetchReach-v4 with its mujoco-4 patch registered)."""
    register_fetch_envs()
    env_id, kwargs = ENVS[name]
    return gym.make(env_id, **kwargs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="alternating measurement rounds")
    parser.add_argument("--episodes", type=int, default=10, help="50-step episodes per env per round")
    args = parser.parse_args()

    ours_name, fetch_name = ENVS
    envs = {name: make_env(name) for name in ENVS}
    # Episodes alternate one by one, so a change in the machine's speed hits both alike.
    times: dict[str, list[list[float]]] = {name: [] for name in envs}
    for r in range(args.rounds):
        for name in envs:
            times[name].append([])
        for e in range(args.episodes):
            for name, env in envs.items():
                times[name][r].extend(episode_step_times(env, seed=100 * r + e))
    rate = {name: 1.0 / statistics.median([t for rnd in v for t in rnd]) for name, v in times.items()}
    round_ratios = [
        statistics.median(f) / statistics.median(o) for o, f in zip(times[ours_name], times[fetch_name])
    ]

    print(
        f"\nSteps per second (1 / median step time), random actions, {args.rounds} rounds of "
        f"{args.episodes} episodes each, the two environments alternating episode by episode:\n"
    )
    print("| environment | steps/s |")
    print("| --- | ---: |")
    for name, v in rate.items():
        print(f"| {name} | {v:,.0f} |")
    print(
        f"\nratio tsrl / FetchReach-v4: {rate[ours_name] / rate[fetch_name]:.2f}x (target >= 4x); "
        f"per round {min(round_ratios):.2f}x to {max(round_ratios):.2f}x\n"
    )

    us = breakdown(envs[ours_name], steps=args.episodes * 50, seed=7)
    print("Breakdown of one tsrl/UR5eReach-v0 step (median microseconds):\n")
    print("| part | us | share of step |")
    print("| --- | ---: | ---: |")
    for k in ("physics", "task maps", "IK", "rest", "whole step"):
        print(f"| {k} | {us[k]:.1f} | {us[k] / us['whole step']:.0%} |")
    print(f"\nwhole step / physics alone: {us['whole step'] / us['physics']:.2f}x (target <= 2x)")

    tasks = {env_id: gym.make(env_id) for env_id in tsrl.ENV_IDS}
    task_times: dict[str, list[float]] = {env_id: [] for env_id in tasks}
    for r in range(args.rounds):
        for e in range(args.episodes):
            for env_id, env in tasks.items():
                task_times[env_id].extend(episode_step_times(env, seed=100 * r + e))
    print("\nEvery built-in task, its default observation and action, random actions:\n")
    print("| task | observation | action dim | steps/s |")
    print("| --- | --- | ---: | ---: |")
    for env_id, env in tasks.items():
        u = env.unwrapped
        rate = 1.0 / statistics.median(task_times[env_id])
        print(f"| {env_id} | {u.task.observation} | {env.action_space.shape[0]} | {rate:,.0f} |")


if __name__ == "__main__":
    main()
