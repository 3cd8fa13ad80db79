"""Does the critic know to stop? For the newest checkpoint of each run, on the run's own evaluation
seeds: the choice between actor and clone as it acts (tsrl.agents.reference), and the same choice with
a third proposal, the hold: the choice's own action with its task-space steps set to zero (the parts'
dimensions; the tool's, the last `--tool-dims`, as the choice's). Per step the proposal whose smaller
critic head is highest acts (the actor on a tie, the hold only where strictly higher than both).

    python studies/learner-from-demos/probe_hold.py RUN_DIR [RUN_DIR ...] [--episodes 100]

Per run and rule: success, the share of steps the hold acts, and for the failures that reached the goal
and left it fast (probe_left.py's "passed through", as the choice acts) the share of their leaving
steps where the critic's smaller head for the hold is above that for the action taken. Both rules step
the episodes in lockstep, as tsrl's Evaluator does. A probe: training is untouched; only how it acts.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from probe_failures import load_run  # type: ignore[import-not-found]
from probe_left import add_class_arguments, left_class  # type: ignore[import-not-found]

from tsrl.agents.reference import heads

ACTOR, CLONE, HOLD = 0, 1, 2


def proposals_and_values(
    policy: Any, batch: dict[str, np.ndarray], tool_dims: int
) -> tuple[np.ndarray, np.ndarray]:
    """(3, n, k) the actor's, the clone's and the hold's actions and (3, n) their smaller critic heads
    on a normalised observation batch; the hold is the actor-or-clone choice with its steps zeroed."""
    obs, _ = policy.obs_to_tensor(batch)
    with th.no_grad():
        actor, clone = policy.actor(obs), policy.reference(obs)
        low = [heads(policy.critic, obs, a).min(dim=1).values for a in (actor, clone)]
        chosen = th.where((low[CLONE] > low[ACTOR])[:, None], clone, actor)
        hold = chosen.clone()
        hold[:, : hold.shape[1] - tool_dims] = 0.0
        low.append(heads(policy.critic, obs, hold).min(dim=1).values)
        return th.stack((actor, clone, hold)).numpy(), th.stack(low).numpy()


def run_episodes(
    evaluator: Any, model: Any, normalizer: Any, with_hold: bool, tool_dims: int
) -> dict[str, Any]:
    """Every evaluation seed's episode in lockstep, acting by the choice (with the hold where asked);
    per episode: success, box positions, goal, per step the hold's and the taken action's value."""
    envs, seeds = evaluator.envs, evaluator.seeds
    observations = [env.reset(seed=s)[0] for env, s in zip(envs, seeds, strict=True)]
    boxes = [[o["achieved_goal"].copy()] for o in observations]
    margins: list[list[float]] = [[] for _ in envs]  # hold's smaller head minus the taken action's
    success = np.zeros(len(envs), dtype=bool)
    holds, steps = 0, 0
    active = list(range(len(envs)))
    while active:
        batch = {key: np.stack([observations[i][key] for i in active]) for key in observations[0]}
        if normalizer is not None:
            batch = normalizer.normalize_obs(batch)
        actions, low = proposals_and_values(model.policy, batch, tool_dims)
        still = []
        for row, i in enumerate(active):
            taken = CLONE if low[CLONE, row] > low[ACTOR, row] else ACTOR
            if with_hold and low[HOLD, row] > low[taken, row]:
                taken = HOLD
            holds += taken == HOLD
            steps += 1
            margins[i].append(float(low[HOLD, row] - low[taken, row]))
            observations[i], _, terminated, truncated, info = envs[i].step(actions[taken, row])
            boxes[i].append(observations[i]["achieved_goal"].copy())
            if terminated or truncated:
                success[i] = bool(info.get("is_success", False))
            else:
                still.append(i)
        active = still
    goals = [o["desired_goal"].copy() for o in observations]
    return {"success": success, "boxes": [np.array(b) for b in boxes], "goals": goals, "margins": margins,
            "hold_share": holds / steps}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument(
        "--tool-dims", type=int, default=1, help="the action's last dimensions the hold keeps"
    )
    add_class_arguments(parser)
    args = parser.parse_args()
    print(
        "| run | env steps | rule | success | hold acts (share of steps) | passed through | of them the hold valued higher |"
    )
    print("| --- | ---: | --- | ---: | ---: | ---: | ---: |")
    for run_dir in args.run_dirs:
        evaluator, model, normalizer, checkpoint = load_run(run_dir, args.episodes)
        for with_hold in (False, True):
            result = run_episodes(evaluator, model, normalizer, with_hold, args.tool_dims)
            passed, higher = 0, 0
            for ok, boxes, goal, margin in zip(
                result["success"], result["boxes"], result["goals"], result["margins"], strict=True
            ):
                left = None if ok else left_class(boxes, goal, args.radius, args.rest, args.lift)
                if left is None or left[0] != "passed through":
                    continue
                leave = int(np.flatnonzero(np.linalg.norm(boxes - goal, axis=1) <= args.radius)[-1])
                passed += 1
                higher += margin[leave] > 0  # boxes[leave] is the state the leaving action was taken in
            print(
                f"| {run_dir.name[-30:]} | {checkpoint.state.env_steps:,} | "
                f"{'with the hold' if with_hold else 'as it acts'} | {result['success'].mean():.2f} | "
                f"{result['hold_share']:.3f} | {passed} | {higher} |",
                flush=True,
            )
        evaluator.close()


if __name__ == "__main__":
    main()
