"""A probe of the fast learner's failures: for the newest checkpoint of each run, the policy as it acts,
its actor alone and its clone alone on the run's own 100 evaluation seeds, with each failed episode
put in one class by the goal distance over its steps (info["distance"], the success radius r):

- left: within r at some step, not at the last (reached, then pushed or carried away);
- near: the last distance in (r, 2r];
- late: the distance still falling over the last 10 steps (by more than r/2), the last above 2r;
- stuck: otherwise (the distance not falling at the end, above 2r).

    python studies/learner-from-demos/probe_failures.py RUN_DIR [RUN_DIR ...] [--episodes 100]

Prints one table row per run and policy. A probe, not a screen: it looks for the cause of a plateau.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents.checkpoint import load_policy, verify_checkpoint
from tsrl.agents.evaluation import Evaluator, eval_seeds
from tsrl.agents.factory import ALGO_CLASSES
from tsrl.agents.run_folder import checkpoint_dirs, load_config

CLASSES = ("left", "near", "late", "stuck")


def load_run(run_dir: Path, episodes: int, at: int | None = None) -> tuple[Evaluator, Any, Any, Any]:
    """(evaluator on the run's own `episodes` evaluation seeds, model, normaliser, checkpoint) of the
    run's checkpoint at `at` env steps, the newest where None. The caller closes the evaluator."""
    cfg = load_config(run_dir)
    dirs = checkpoint_dirs(run_dir)
    chosen = dirs[-1] if at is None else next(d for d in dirs if d.name.endswith(f"{at:010d}"))
    checkpoint = verify_checkpoint(chosen, cfg.agent.normalize, for_training=False)
    model, normalizer = load_policy(checkpoint, ALGO_CLASSES[cfg.agent.algo])
    return Evaluator(cfg, eval_seeds(cfg.seed, episodes)), model, normalizer, checkpoint


def episodes(evaluator: Evaluator, model: Any, normalizer: Any) -> list[tuple[bool, list[float]]]:
    """(success at the last step, goal distance per step) per evaluation seed."""
    distances: list[list[float]] = [[] for _ in evaluator.seeds]
    success = [False] * len(evaluator.seeds)

    def record(i: int, info: dict[str, Any]) -> None:
        distances[i].append(float(info["distance"]))
        success[i] = bool(info["is_success"])  # the last step's stays

    evaluator.evaluate(model, normalizer, on_step=record)
    return list(zip(success, distances, strict=True))


def failure_class(distances: list[float], radius: float) -> str:
    d = np.asarray(distances)
    if (d <= radius).any():
        return "left"
    if d[-1] <= 2 * radius:
        return "near"
    if len(d) > 10 and d[-11] - d[-1] > radius / 2:
        return "late"
    return "stuck"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--radius", type=float, default=0.05, help="the task's success radius [m]")
    args = parser.parse_args()
    print(
        "| run | env steps | policy | success | "
        + " | ".join(CLASSES)
        + " | median last distance of failures [m] |"
    )
    print("| --- | ---: | --- | ---: | " + " | ".join("---:" for _ in CLASSES) + " | ---: |")
    for run_dir in args.run_dirs:
        evaluator, model, normalizer, checkpoint = load_run(run_dir, args.episodes)
        policy = model.policy
        acting = policy._predict
        for name in ("acting", "actor", "reference"):
            if name == "acting":
                policy._predict = acting  # type: ignore[method-assign]
            else:
                net = getattr(policy, name)
                policy._predict = lambda obs, deterministic=False, net=net: net(obs)  # type: ignore[method-assign]
            results = episodes(evaluator, model, normalizer)
            failed = [d for ok, d in results if not ok]
            classes = Counter(failure_class(d, args.radius) for d in failed)
            last = float(np.median([d[-1] for d in failed])) if failed else float("nan")
            print(
                f"| {run_dir.name[-30:]} | {checkpoint.state.env_steps:,} | {name} | "
                f"{np.mean([ok for ok, _ in results]):.2f} | "
                + " | ".join(str(classes[c]) for c in CLASSES)
                + f" | {last:.3f} |",
                flush=True,
            )
        evaluator.close()


if __name__ == "__main__":
    main()
