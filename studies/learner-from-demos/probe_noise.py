"""Probe (README, pre-registration 12's result): how much of the fast learner's training success does
its exploration noise cost on a task?

For a run's checkpoint, the clone (or the policy as it acts) on the run's own evaluation seeds, with
Gaussian noise of each given std added to every action and clipped to [-1, 1], as TD3's explore
episodes act (stable-baselines3's `_sample_action`); the success of each.

    python studies/learner-from-demos/probe_noise.py RUN_DIR --at 35000 --noise 0 0.05 0.1 [--policy clone] [--dims 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from probe_failures import load_run  # type: ignore[import-not-found]

from tsrl.agents.reference import CLONE


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--at", type=int, default=None, help="the checkpoint's env steps (default: newest)")
    parser.add_argument("--noise", type=float, nargs="+", required=True, help="stds on the [-1, 1] action")
    parser.add_argument("--policy", choices=("clone", "acting"), default="clone")
    parser.add_argument(
        "--dims", type=int, nargs="+", default=None, help="action dimensions noised (default: all)"
    )
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    dims = "all" if args.dims is None else " ".join(map(str, args.dims))
    print("| policy | noise std | action dimensions noised | success |")
    print("| --- | ---: | --- | ---: |")
    for std in args.noise:
        evaluator, model, normalizer, _ = load_run(args.run_dir, args.episodes, args.at)
        policy = model.policy
        policy.episode_policy = CLONE if args.policy == "clone" else None
        acting = policy._predict
        rng = np.random.default_rng(0)

        def noisy(
            obs: Any, deterministic: bool = False, acting: Any = acting, std: float = std, rng: Any = rng
        ) -> th.Tensor:
            action = acting(obs, deterministic)
            noise = th.as_tensor(rng.normal(0.0, std, action.shape), dtype=action.dtype)
            if args.dims is not None:
                noise[:, [d for d in range(action.shape[1]) if d not in args.dims]] = 0.0
            return th.clamp(action + noise, -1.0, 1.0)

        policy._predict = noisy  # type: ignore[method-assign]
        with th.no_grad():
            result = evaluator.evaluate(model, normalizer)
        evaluator.close()
        print(f"| {args.policy} | {std:g} | {dims} | {result.success_rate:.2f} |", flush=True)


if __name__ == "__main__":
    main()
