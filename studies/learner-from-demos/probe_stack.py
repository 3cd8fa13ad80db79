"""The stack's failures, split by what happened to each box: for the newest checkpoint of each run, the
policy as it acts on the run's own evaluation seeds, each failed episode put in the first class that
fits (box: the first, to its goal on the table; box_b: the second, onto it; placed: within the task's
3 cm of its goal):

- first not lifted: the first box never lifted (more than 1 cm above its start);
- first not placed: lifted, not placed at the last step, never placed before;
- first knocked: placed at some step, not at the last;
- second not lifted: the first placed at the last step, the second never lifted;
- second knocked: the second placed at some step, not at the last;
- second not placed: the second lifted, not placed at the last step, never placed before.

(The study's tables made before this class was added have no "second knocked": their "second not
placed" holds both.)

    python studies/learner-from-demos/probe_stack.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--knocks]

`--knocks` also prints, per "first knocked" episode, the step at which the first box last left its
goal and where the second box was then, relative to the first (knock_geometry), and over won and lost
episodes how often the finger command changed sign and the acting proposal switched (acting_summary).

A probe, not a screen: it looks for the cause of a plateau.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
from probe_failures import load_run  # type: ignore[import-not-found]

CLASSES = (
    "first not lifted", "first not placed", "first knocked", "second not lifted", "second knocked",
    "second not placed",
)  # fmt: skip
LIFT = 0.01  # [m] above the start height
PLACED = 0.03  # [m] the task's success radius per box


def stack_class(first: np.ndarray, second: np.ndarray, goals: np.ndarray) -> str:
    """first, second: (steps + 1, 3) box positions [m, world], the first row at reset; goals: (2, 3)."""
    placed = np.linalg.norm(first - goals[0], axis=1) < PLACED
    if not (first[:, 2] > first[0, 2] + LIFT).any():
        return "first not lifted"
    if not placed[-1]:
        return "first knocked" if placed.any() else "first not placed"
    if not (second[:, 2] > second[0, 2] + LIFT).any():
        return "second not lifted"
    return (
        "second knocked"
        if (np.linalg.norm(second - goals[1], axis=1) < PLACED).any()
        else "second not placed"
    )


def knock_geometry(
    first: np.ndarray, second: np.ndarray, tcp: np.ndarray, goals: np.ndarray, acted: list[tuple[str, float]]
) -> str:
    """The step at which a knocked first box last left its goal, and the second box and the tool
    centre point then, relative to the first [cm]: height above it, horizontal offset; and over the
    8 steps before it, which proposal acted (A: actor, C: clone) with its finger command (-1 closed,
    +1 open)."""
    placed = np.linalg.norm(first - goals[0], axis=1) < PLACED
    step = int(np.flatnonzero(placed[:-1] & ~placed[1:])[-1]) + 1
    box, hand = (second[step] - first[step]) * 100, (tcp[step] - first[step]) * 100
    before = " ".join(f"{who}{finger:+.1f}" for who, finger in acted[max(0, step - 8) : step])
    return (
        f"step {step - 1}: second box {box[2]:+.1f} cm above the first, {np.linalg.norm(box[:2]):.1f} cm "
        f"beside it (lifted {(second[step, 2] - second[0, 2]) * 100:.1f} cm); tcp {hand[2]:+.1f} cm above, "
        f"{np.linalg.norm(hand[:2]):.1f} cm beside; acted before: {before}"
    )


def acting_summary(acted: list[list[tuple[str, float]]], success: list[bool]) -> str:
    """Per episode, over won and over lost ones: the finger command's sign changes, the share of
    them at a switch of proposal, the proposal's switches, and the clone's share of the steps."""
    parts = []
    for won in (True, False):
        episodes = [a for a, ok in zip(acted, success, strict=True) if ok == won]
        if not episodes:
            continue
        flips = switches = at_switch = clone_steps = steps = 0
        for steps_acted in episodes:
            who = [w for w, _ in steps_acted]
            sign = np.sign([f for _, f in steps_acted])
            steps, clone_steps = steps + len(who), clone_steps + who.count("C")
            for t in range(1, len(who)):
                switch = who[t] != who[t - 1]
                switches += switch
                if sign[t] * sign[t - 1] < 0:
                    flips, at_switch = flips + 1, at_switch + switch
        parts.append(
            f"{'won' if won else 'lost'} {len(episodes)}: finger sign changes {flips / len(episodes):.1f} per "
            f"episode ({at_switch / max(flips, 1):.2f} at a switch), proposal switches "
            f"{switches / len(episodes):.1f} per episode, clone on {clone_steps / steps:.2f} of the steps"
        )
    return "; ".join(parts)


def recording_choices(policy: Any) -> list[list[tuple[str, float]]]:
    """Wraps `policy._predict` (tsrl.agents.reference.ReferenceTD3Policy) so that each call stores, per
    row, which proposal acted ("A" actor, "C" clone) and its last action component (the fingers), in
    the list returned (one inner list per call)."""
    calls: list[list[tuple[str, float]]] = []
    predict = policy._predict

    def _predict(observation: Any, deterministic: bool = False) -> Any:
        action = predict(observation, deterministic)
        clone = policy.reference(observation)
        calls.append(
            [("C" if c else "A", float(a[-1])) for c, a in zip((action == clone).all(dim=1), action)]
        )
        return action

    policy._predict = _predict
    return calls


def probe(run_dir: Path, episodes: int, knocks: bool = False) -> str:
    """One table row for the run's newest checkpoint on its own `episodes` evaluation seeds; with
    `knocks`, a line per "first knocked" episode before it (knock_geometry)."""
    evaluator, model, normalizer, checkpoint = load_run(run_dir, episodes)
    envs: list[Any] = [env.unwrapped for env in evaluator.envs]
    tracks: list[list[np.ndarray]] = [[] for _ in envs]  # per step: first box, second box, tcp
    goals = np.zeros((len(envs), 2, 3))
    success = [False] * len(envs)
    calls = recording_choices(model.policy)
    acted: list[list[tuple[str, float]]] = [[] for _ in envs]  # per step: who acted, finger command

    def record(i: int, info: dict[str, Any]) -> None:
        acted[i].append(calls[-1].pop(0))  # steps come in the order of the call's rows
        data = envs[i].data
        both = np.stack([data.body("box").xpos, data.body("box_b").xpos, data.site("tcp").xpos])
        if not tracks[i]:  # the reset's positions: the boxes have not moved in the first step's physics
            tracks[i].append(both)
        tracks[i].append(both)
        goals[i] = [data.mocap_pos[envs[i].goal.marker_mocap(p)] for p in range(2)]
        success[i] = bool(info["is_success"])

    evaluator.evaluate(model, normalizer, on_step=record)
    evaluator.close()
    failed = {
        i: stack_class(np.asarray(tracks[i])[:, 0], np.asarray(tracks[i])[:, 1], goals[i])
        for i in range(len(envs))
        if not success[i]
    }
    classes = Counter(failed.values())
    if knocks:
        print(acting_summary(acted, success))
        for i, kind in failed.items():
            if kind == "first knocked":
                track = np.asarray(tracks[i])
                where = knock_geometry(track[:, 0], track[:, 1], track[:, 2], goals[i], acted[i])
                print(f"episode {i}: {where}")
    return (
        f"| {run_dir.name[-32:]} | {checkpoint.state.env_steps:,} | {np.mean(success):.2f} | "
        + " | ".join(str(classes[c]) for c in CLASSES)
        + " |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--knocks", action="store_true", help="where the second box was at each knock")
    args = parser.parse_args()
    print("| run | env steps | success | " + " | ".join(CLASSES) + " |")
    print("| --- | ---: | ---: | " + " | ".join("---:" for _ in CLASSES) + " |")
    for run_dir in args.run_dirs:
        print(probe(run_dir, args.episodes, args.knocks), flush=True)


if __name__ == "__main__":
    main()
