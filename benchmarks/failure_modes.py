"""Why a trained object-moving policy fails (issue 24: "report the curve and what limits it"): its final
policy's deterministic episodes, each failed one put in one class by what the object did.

    python benchmarks/failure_modes.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--save NAME]

Per run: the newest usable checkpoint's policy on `--episodes` fresh evaluation episodes (the seeds
`tsrl evaluate` uses, none seen in training's evaluations), the run's own task, observation and
action. The object is the body whose position is the task's goal (`[goal] map = "position(<body>)"`).
Classes of a failed episode, in this order:

- *not moved*: the object never moved 1 cm from where it started;
- *reached, then lost*: it was within the success tolerance at some step but not at the last;
- *short of the goal*: it ended at most half as far from the goal as it started (moved the right
  way, too little);
- *moved, not towards the goal*: it moved, and ended more than half as far from the goal as it started.

Also per run: the median number of steps successful episodes took to first meet the tolerance.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

from tsrl.agents.evaluation import fresh_eval_seeds, load_run_policy, policy_action
from tsrl.agents.factory import make_env
from tsrl.envs.base import TaskEnv

MOVED = 0.01  # m
CLASSES = ("success", "not moved", "reached, then lost", "short of the goal", "moved, not towards the goal")


def goal_body(env: TaskEnv) -> str:
    """The body whose position is the goal ("position(box)" -> "box"); ValueError for other goals."""
    spec = env.task.goal.map
    if not (spec.startswith("position(") and spec.endswith(")") and "," not in spec):
        raise ValueError(f"{env.task.name}: goal map {spec!r}; failure classes need a goal position(<body>)")
    return spec[len("position(") : -1]


def classify(start: np.ndarray, path: np.ndarray, goal: np.ndarray, tolerance: float) -> str:
    """The class of one episode from the object's start (3,), its positions after each step (T, 3) and
    the goal (3,) [m, world frame]."""
    distance = np.linalg.norm(path - goal, axis=1)
    if distance[-1] <= tolerance:
        return "success"
    if np.max(np.linalg.norm(path - start, axis=1)) < MOVED:
        return "not moved"
    if np.any(distance <= tolerance):
        return "reached, then lost"
    if distance[-1] <= 0.5 * np.linalg.norm(start - goal):
        return "short of the goal"
    return "moved, not towards the goal"


def failure_modes(run_dir: Path, episodes: int) -> dict[str, Any]:
    """One row: the run, its env steps, and per class the number of episodes."""
    cfg, model, normalizer, checkpoint = load_run_policy(run_dir)
    env = make_env(cfg)
    base = env.unwrapped
    assert isinstance(base, TaskEnv)
    body = goal_body(base)
    counts = dict.fromkeys(CLASSES, 0)
    steps_to_success = []
    for seed in fresh_eval_seeds(cfg.seed, episodes):
        obs, _ = env.reset(seed=seed)
        start = base.data.body(body).xpos.copy()
        goal = np.asarray(obs["desired_goal"], dtype=float)
        path = []
        done = False
        while not done:
            obs, _, terminated, truncated, _ = env.step(policy_action(model, normalizer, obs))
            path.append(base.data.body(body).xpos.copy())
            done = terminated or truncated
        positions = np.array(path)
        kind = classify(start, positions, goal, base.task.success.position)
        counts[kind] += 1
        if kind == "success":
            within = np.linalg.norm(positions - goal, axis=1) <= base.task.success.position
            steps_to_success.append(int(np.argmax(within)) + 1)
    env.close()
    return {
        "run": run_dir.name,
        "env_id": cfg.env_id,
        "env_steps": checkpoint.state.env_steps,
        "episodes": episodes,
        **counts,
        "median_steps_to_success": float(np.median(steps_to_success)) if steps_to_success else float("nan"),
    }


def render(rows: list[dict[str, Any]]) -> list[str]:
    """The table (markdown) from `failure_modes`' rows (or their CSV strings)."""
    lines = [
        "| run | env steps | " + " | ".join(CLASSES) + " | median steps to success |",
        "| --- | ---: | " + " | ".join("---:" for _ in CLASSES) + " | ---: |",
    ]
    for r in rows:
        n = int(r["episodes"])
        cells = " | ".join(f"{int(r[c])} ({int(r[c]) / n:.0%})" for c in CLASSES)
        median = float(r["median_steps_to_success"])
        lines.append(
            f"| `{r['run']}` | {int(r['env_steps']):,} | {cells} | {'-' if np.isnan(median) else f'{median:.0f}'} |"
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("runs", type=Path, nargs="+", metavar="RUN_DIR")
    parser.add_argument("--episodes", type=int, default=100)
    add_save_argument(parser, "failure-modes")
    args = parser.parse_args()
    if args.episodes < 1:
        parser.error(f"--episodes must be >= 1; got {args.episodes}")
    with Measurement(args.save, __file__, "benchmarks/failure_modes.py:table", "docs/training.md") as out:
        rows = [failure_modes(run, args.episodes) for run in args.runs]
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))


if __name__ == "__main__":
    main()
