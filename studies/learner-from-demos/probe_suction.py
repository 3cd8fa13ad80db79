"""The suction pick-and-place's failures split by what happened to the box (probe_failures' "stuck"
class, looked into): for the newest checkpoint of each run, the policy as it acts on the run's own
evaluation seeds, each failed episode put in one class by the box's height over the table and the
suction cup's command over its steps:

- untouched: the box never lifted (more than 1 cm) and moved less than 1 cm;
- pushed: never lifted, moved 1 cm or more (slid or knocked on the table);
- dropped: lifted at some step, back on the table at the last, the cup off;
- held: lifted and still up at the last step (carried, but not within the radius);
- other: anything else (lifted, on the table at the end with the cup on).

    python studies/learner-from-demos/probe_suction.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--at ENV_STEPS]

Prints one row per run, with the successes' and failures' median step of the first lift, and the share
of failures whose goal is lifted (above the table). A probe, not a screen.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from probe_failures import load_run  # type: ignore[import-not-found]

CLASSES = ("untouched", "pushed", "dropped", "held", "other")
LIFT = 0.01  # [m] above the box's start height
MOVED = 0.01  # [m] in the table's plane


def box_class(box: np.ndarray, cup_on: np.ndarray) -> str:
    """box: (steps + 1, 3) positions [m, world], the first at reset; cup_on: (steps,) the cup's command."""
    lifted = box[:, 2] > box[0, 2] + LIFT
    if not lifted.any():
        return "pushed" if np.linalg.norm(box[-1, :2] - box[0, :2]) >= MOVED else "untouched"
    if lifted[-1]:
        return "held"
    return "dropped" if not cup_on[-1] else "other"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--at", type=int, default=None, help="the checkpoint at these env steps (newest)")
    args = parser.parse_args()
    print(
        "| run | env steps | success | "
        + " | ".join(CLASSES)
        + " | first lift, successes (median step) | first lift, failures | failures with a lifted goal |"
    )
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in CLASSES) + " | ---: | ---: | ---: |")
    for run_dir in args.run_dirs:
        print(probe(run_dir, args.episodes, args.at), flush=True)


def probe(run_dir: Path, episodes: int, at: int | None) -> str:
    """One table row: the run's checkpoint at `at` env steps (the newest where None) on its own
    `episodes` evaluation seeds."""
    evaluator, model, normalizer, checkpoint = load_run(run_dir, episodes, at)
    envs: list[Any] = [env.unwrapped for env in evaluator.envs]
    boxes: list[list[np.ndarray]] = [[] for _ in envs]
    cup: list[list[bool]] = [[] for _ in envs]
    success = [False] * len(envs)
    goal_z = np.zeros(len(envs))

    def record(i: int, info: dict[str, Any]) -> None:
        data = envs[i].data
        if not boxes[i]:  # the reset's position: the box has not moved in the first step's physics
            boxes[i].append(data.body("box").xpos.copy())
        boxes[i].append(data.body("box").xpos.copy())
        cup[i].append(bool(data.ctrl[envs[i].interface.tool_ctrl] > 0.5))
        success[i] = bool(info["is_success"])
        goal_z[i] = float(data.mocap_pos[envs[i].goal.marker_mocap(0), 2])  # the goal's marker

    evaluator.evaluate(model, normalizer, on_step=record)
    evaluator.close()
    classes: Counter[str] = Counter()
    lifts: dict[bool, list[int]] = {True: [], False: []}
    for i in range(len(envs)):
        box = np.asarray(boxes[i])
        lifted = np.flatnonzero(box[1:, 2] > box[0, 2] + LIFT)
        if lifted.size:
            lifts[success[i]].append(int(lifted[0]) + 1)
        if not success[i]:
            classes[box_class(box, np.asarray(cup[i]))] += 1
    failed = [i for i in range(len(envs)) if not success[i]]
    lifted_goal = [float(goal_z[i] > boxes[i][0][2] + LIFT) for i in failed]
    return (
        f"| {run_dir.name[-32:]} | {checkpoint.state.env_steps:,} | {np.mean(success):.2f} | "
        + " | ".join(str(classes[c]) for c in CLASSES)
        + f" | {np.median(lifts[True]) if lifts[True] else float('nan'):.0f}"
        + f" | {np.median(lifts[False]) if lifts[False] else float('nan'):.0f}"
        + f" | {np.mean(lifted_goal) if lifted_goal else float('nan'):.2f} |"
    )


if __name__ == "__main__":
    main()
