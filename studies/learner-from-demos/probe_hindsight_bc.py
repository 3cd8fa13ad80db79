"""Probe: does BC of few demonstrations generalise further when their goals are relabelled in
hindsight (goal-conditioned supervised learning, Ghosh et al. 2019; HER's "future" goals)?

Each demonstrated step (observation, goal, action) is kept, and `--copies` more copies of it are made
with the goal replaced by the achieved goal of a later step of the same episode, drawn uniformly (the
environment's `relabel` recomputes the goal-dependent features, as feature HER does): a demonstration
that carried the box through a place also shows how to bring it there. The rows become one-step
episodes of a demonstration file (its next observation relabelled alike), and pre-registration 1's BC
(run.py bc_probe) trains on it; its row goes to data/probes.csv as arm `hbcN` (N demonstrations).

    python studies/learner-from-demos/probe_hindsight_bc.py PandaPickPlaceGripper-v0 --demos 10 --seeds 0 1 2
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
import run  # type: ignore[import-not-found]

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents.demo_files import Demonstrations, load_demos, save_demos
from tsrl.envs.keys import OBS_KEYS


def hindsight_rows(demos: Demonstrations, env: gym.Env, copies: int, seed: int) -> Demonstrations:
    """Every step of `demos` as a one-step episode, then `copies` relabelled copies of each (module
    docstring), under the file's meta."""
    rng = np.random.default_rng(seed)
    n, t = demos.n_episodes, demos.episode_steps
    episode, step = np.divmod(np.arange(n * t), t)
    episode = np.concatenate([episode] * (copies + 1))
    step = np.concatenate([step] * (copies + 1))
    original = np.arange(episode.size) < n * t
    later = step + 1 + (rng.random(episode.size) * (t - step)).astype(int)  # uniform over step+1..t
    goals = np.where(
        original[:, None], demos.desired_goal[episode, step], demos.achieved_goal[episode, later]
    )
    unwrapped = env.unwrapped
    now = {key: getattr(demos, key)[episode, step] for key in OBS_KEYS}
    after = {key: getattr(demos, key)[episode, step + 1] for key in OBS_KEYS}
    now, after = unwrapped.relabel(now, goals), unwrapped.relabel(after, goals)  # type: ignore[attr-defined]
    arrays = {
        key: np.stack([now[key], after[key]], axis=1).astype(getattr(demos, key).dtype) for key in OBS_KEYS
    }
    reward = unwrapped.compute_reward(after["achieved_goal"], goals, [{}] * goals.shape[0])  # type: ignore[attr-defined]
    success = unwrapped.goal.success(after["achieved_goal"], goals)  # type: ignore[attr-defined]
    return Demonstrations(
        **arrays,
        actions=demos.actions[episode, step][:, None],
        rewards=np.asarray(reward, dtype=demos.rewards.dtype)[:, None],
        is_success=success[:, None].astype(demos.is_success.dtype),
        seeds=demos.seeds[episode],
        meta=dict(demos.meta) | {"kept": int(episode.size), "hindsight_copies": copies},
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", choices=sorted(run.BUDGETS))
    parser.add_argument("--demos", type=int, default=10)
    parser.add_argument("--copies", type=int, default=4, help="relabelled copies of each step")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--out", type=Path, default=Path("results/learner-from-demos"))
    args = parser.parse_args()
    demos = load_demos(run.demo_file(args.out, args.task, args.demos))
    env = gym.make(f"tsrl/{args.task}")
    path = args.out / "demos" / f"{args.task}-{args.demos}-hindsight{args.copies}.npz"
    save_demos(hindsight_rows(demos, env, args.copies, seed=0), path)
    env.close()
    for seed in args.seeds:
        run.bc_probe(f"hbc{args.demos}", args.task, seed, path, args.out)


if __name__ == "__main__":
    main()
