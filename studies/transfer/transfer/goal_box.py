"""Descriptive, not pre-registered: where do zero-shot reach policies fail on the other arm?

The two reach tasks sample goals in boxes of the same size (half-extent 0.15 m) around different
centres in world coordinates (UR5e (-0.4919, -0.1333, 0.4179), Panda (-0.4569, 0, 0.3975)), and fs1
reads world positions. This script re-runs the transfer evaluations of experiments/transfer.toml
(each seed's final policy, the same 100 fresh episodes as its [[evaluate]] arms) one episode at a
time and splits them by whether the goal lies inside the training arm's goal box. Prints a markdown
table; `python studies/transfer/transfer/goal_box.py RESULTS_DIR > studies/transfer/transfer/goal_box.md`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

from tsrl.agents.evaluation import fresh_eval_seeds, load_run_policy
from tsrl.agents.transfer import base_task, eval_task
from tsrl.envs import TASK_ENV_ID

EPISODES = 100
PAIRS = (("tsrl/UR5eReach-v0", "tsrl/PandaReach-v0"), ("tsrl/PandaReach-v0", "tsrl/UR5eReach-v0"))


def episodes(run_dir: Path, target: str) -> tuple[np.ndarray, np.ndarray]:
    """Goals (n, 3) and true success (n,) of the run's policy on `target`'s fresh episodes."""
    cfg, model, normalizer, _ = load_run_policy(run_dir)
    task = eval_task(cfg, target)
    env = gym.make(TASK_ENV_ID, **task.env_kwargs(cfg))
    goals, success = [], []
    for seed in fresh_eval_seeds(cfg.seed, EPISODES):
        obs, _ = env.reset(seed=seed)
        goals.append(obs["desired_goal"].copy())
        done = False
        while not done:
            batch = {k: v[None] for k, v in obs.items()}
            if normalizer is not None:
                batch = normalizer.normalize_obs(batch)
            action, _ = model.predict(batch, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action[0])
            done = terminated or truncated
        success.append(bool(info.get("true_success", info["is_success"])))
    env.close()
    return np.array(goals), np.array(success)


def main(results_dir: Path) -> None:
    print(
        "| trained on | evaluated on | goals inside the training box: success (episodes) | outside: success (episodes) |"
    )
    print("| --- | --- | --- | --- |")
    for trained, target in PAIRS:
        box = base_task(trained).goal.position
        centre, half = np.array(box.center), np.array(box.half_extent)
        inside_ok, inside_n, outside_ok, outside_n = 0, 0, 0, 0
        for run_dir in sorted(results_dir.glob(f"{trained.replace('/', '-')}__*")):
            goals, success = episodes(run_dir, target)
            inside = np.all(np.abs(goals - centre) <= half + 1e-9, axis=1)
            inside_ok += int(success[inside].sum())
            inside_n += int(inside.sum())
            outside_ok += int(success[~inside].sum())
            outside_n += int((~inside).sum())
        print(
            f"| {trained} | {target} | {inside_ok / inside_n:.3f} ({inside_n}) | "
            f"{outside_ok / outside_n:.3f} ({outside_n}) |"
        )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
