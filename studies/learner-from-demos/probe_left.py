"""A probe of the failures that reach the goal and leave it (probe_failures.py's "left" class), for
the newest checkpoint of each run, the policy as it acts on the run's own evaluation seeds: how the
box left: fast (through the goal and on), dropped, or slowly; and whether it had been lifted above the
table by more than `--lift` (carried) or not (pushed).

    python studies/learner-from-demos/probe_left.py RUN_DIR [RUN_DIR ...] [--episodes 100]

Per run: the policy's success, its failures, and the "left" ones split as

- dropped: lifted before it left, and lower by more than the radius 5 steps after leaving;
- passed through: not dropped, moving more than half the radius on the step it left;
- drifted off: the rest (leaving slower);

each also counted as pushed (never lifted) or carried.

Heights are the achieved goal's z [m] in the task's frame, the table's box resting at `--rest`.
Descriptive (a probe): it names a failure's mechanism, not its cause.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from probe_failures import load_run

CLASSES = ("dropped", "passed through", "drifted off")


def rollouts(evaluator: Any, model: Any, normalizer: Any) -> list[tuple[bool, np.ndarray, np.ndarray]]:
    """(success at the last step, (T + 1, 3) box positions, (3,) goal) per evaluation seed."""
    out = []
    for env, seed in zip(evaluator.envs, evaluator.seeds, strict=True):
        obs, _ = env.reset(seed=seed)
        boxes, done, info = [obs["achieved_goal"].copy()], False, {}
        while not done:
            batch = {key: value[None] for key, value in obs.items()}
            if normalizer is not None:
                batch = normalizer.normalize_obs(batch)
            action, _ = model.predict(batch, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action[0])
            boxes.append(obs["achieved_goal"].copy())
            done = terminated or truncated
        out.append((bool(info["is_success"]), np.array(boxes), obs["desired_goal"].copy()))
    return out


def left_class(
    boxes: np.ndarray, goal: np.ndarray, radius: float, rest: float, lift: float
) -> tuple[str, bool] | None:
    """(CLASSES' name, lifted) of a failed episode that was within `radius` of `goal` at some step;
    None for one that never was."""
    distance = np.linalg.norm(boxes - goal, axis=1)
    inside = np.flatnonzero(distance <= radius)
    if inside.size == 0:
        return None
    leave = int(inside[-1])  # the last step inside; the next is outside (the episode failed)
    lifted = bool((boxes[: leave + 1, 2] > rest + lift).any())
    if lifted and boxes[leave, 2] - boxes[min(leave + 5, len(boxes) - 1), 2] > radius:
        return "dropped", lifted
    speed = float(np.linalg.norm(boxes[leave + 1] - boxes[leave]))
    return ("passed through" if speed > radius / 2 else "drifted off"), lifted


def add_class_arguments(parser: argparse.ArgumentParser) -> None:
    """left_class's thresholds as options: --radius, --rest, --lift [m]."""
    parser.add_argument("--radius", type=float, default=0.05, help="the task's success radius [m]")
    parser.add_argument("--rest", type=float, default=0.02, help="the box's height resting on the table [m]")
    parser.add_argument(
        "--lift", type=float, default=0.02, help="height above rest that counts as lifted [m]"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    add_class_arguments(parser)
    args = parser.parse_args()
    print(
        "| run | env steps | success | failures | left (pushed) | "
        + " | ".join(f"{c} (pushed)" for c in CLASSES)
        + " |"
    )
    print("| --- | ---: | ---: | ---: | ---: | " + " | ".join("---:" for _ in CLASSES) + " |")
    for run_dir in args.run_dirs:
        evaluator, model, normalizer, checkpoint = load_run(run_dir, args.episodes)
        results = rollouts(evaluator, model, normalizer)
        evaluator.close()
        failed = [(boxes, goal) for ok, boxes, goal in results if not ok]
        classes = [left_class(b, g, args.radius, args.rest, args.lift) for b, g in failed]
        left = [c for c in classes if c is not None]
        counts, pushed = Counter(c for c, _ in left), Counter(c for c, lifted in left if not lifted)
        print(
            f"| {run_dir.name[-30:]} | {checkpoint.state.env_steps:,} | "
            f"{np.mean([ok for ok, _, _ in results]):.2f} | {len(failed)} | "
            f"{len(left)} ({sum(pushed.values())}) | "
            + " | ".join(f"{counts[c]} ({pushed[c]})" for c in CLASSES)
            + " |",
            flush=True,
        )


if __name__ == "__main__":
    main()
