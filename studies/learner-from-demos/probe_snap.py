"""Probe (README, "The stack's failures"): is the clone's gripper command, regressed between the
demonstrations' -1 (closed) and +1 (open), what drops the boxes?

For the newest checkpoint of each run, the policy on the run's own evaluation seeds as it acts, and
with its last action dimension (the gripper's width) snapped to the sign of what it outputs (-1 or
+1, as every demonstrated command is); also the share of steps whose raw command lies in (-0.9, 0.9).

    python studies/learner-from-demos/probe_snap.py RUN_DIR [RUN_DIR ...] [--episodes 100]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from probe_failures import episodes, load_run  # type: ignore[import-not-found]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    print("| run | env steps | gripper command | success | steps with a command in (-0.9, 0.9) |")
    print("| --- | ---: | --- | ---: | ---: |")
    for run_dir in args.run_dirs:
        evaluator, model, normalizer, checkpoint = load_run(run_dir, args.episodes)
        policy = model.policy
        acting = policy._predict
        for snap in (False, True):
            commands: list[float] = []

            def act(
                obs: Any,
                deterministic: bool = False,
                snap: bool = snap,
                acting: Any = acting,
                commands: list[float] = commands,
            ) -> th.Tensor:
                action = acting(obs, deterministic)
                commands.extend(action[:, -1].tolist())
                if snap:
                    action = action.clone()
                    action[:, -1] = th.where(action[:, -1] > 0, 1.0, -1.0)
                return action

            policy._predict = act  # type: ignore[method-assign]
            results = episodes(evaluator, model, normalizer)
            between = float(np.mean(np.abs(commands) < 0.9))
            print(
                f"| {run_dir.name[-30:]} | {checkpoint.state.env_steps:,} | {'snapped' if snap else 'as output'} | "
                f"{np.mean([ok for ok, _ in results]):.2f} | {between:.3f} |",
                flush=True,
            )
        evaluator.close()


if __name__ == "__main__":
    main()
