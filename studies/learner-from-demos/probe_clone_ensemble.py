"""Probe (README, pre-registration 25): does the mean action of several behaviour clones of the same
demonstrations succeed more often than each clone alone?

Trains pre-registration 1's BC arm (`bcN`) for each seed given (or reuses its run folder under OUT),
then evaluates each clone's final policy and the ensemble (the members' deterministic actions
averaged) on the same 100 fresh seeds (those of the first member's run: fresh_eval_seeds(seed, 100)).
The members share the demonstrations, so their observation normalisers are equal (checked).

    python studies/learner-from-demos/probe_clone_ensemble.py bc100 PandaStack-v0 --seeds 0 1 2 3 4 --out DIR
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from run import EVAL_EPISODES, arm_config, demo_count, demo_file  # type: ignore[import-not-found]

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import train
from tsrl.agents.checkpoint import load_policy, usable_checkpoint
from tsrl.agents.evaluation import Evaluator, fresh_eval_seeds
from tsrl.agents.factory import ALGO_CLASSES
from tsrl.agents.run_folder import CONFIG_FILE


class MeanAction:
    """The members' deterministic actions averaged: (n, k) from a batch of n observations."""

    def __init__(self, members: list[Any]):
        self.members = members

    def predict(self, observation: Any, deterministic: bool = True) -> tuple[np.ndarray, None]:
        actions = [m.predict(observation, deterministic=True)[0] for m in self.members]
        return np.mean(actions, axis=0), None


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("arm", help="a BC arm of run.py: bc100, bc10")
    parser.add_argument("task")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    if not args.arm.startswith("bc"):
        raise SystemExit(f"arm {args.arm!r}: accepted: a BC arm (bc100, bc10)")
    demos = demo_file(args.out, args.task, demo_count(args.arm))
    members, normalizers = [], []
    for seed in args.seeds:
        cfg = arm_config(args.arm, args.task, seed, demos)
        parent = args.out / args.arm / args.task
        run_dir = parent / cfg.run_name
        if not (run_dir / CONFIG_FILE).is_file():
            run_dir = train(cfg, parent, progress_bar=False)
        checkpoint = usable_checkpoint(run_dir, cfg.agent.normalize, for_training=False)
        assert checkpoint is not None
        model, normalizer = load_policy(checkpoint, ALGO_CLASSES[cfg.agent.algo])
        members.append(model)
        normalizers.append(normalizer)
    for other in normalizers[1:]:  # one normaliser serves every member
        for key in normalizers[0].obs_rms:
            assert np.array_equal(other.obs_rms[key].mean, normalizers[0].obs_rms[key].mean), key
    first = arm_config(args.arm, args.task, args.seeds[0], demos)
    evaluator = Evaluator(first, fresh_eval_seeds(args.seeds[0], EVAL_EPISODES))
    try:
        print(f"| {args.task} {args.arm} | success on {EVAL_EPISODES} fresh seeds |")
        print("| --- | ---: |")
        alone = []
        for seed, model in zip(args.seeds, members, strict=True):
            alone.append(evaluator.evaluate(model, normalizers[0]).success_rate)
            print(f"| clone of seed {seed} | {alone[-1]:.2f} |", flush=True)
        print(f"| the clones alone, mean | {np.mean(alone):.3f} |")
        ensemble = evaluator.evaluate(MeanAction(members), normalizers[0]).success_rate  # type: ignore[arg-type]
        print(f"| mean action of the {len(members)} clones | {ensemble:.2f} |")
    finally:
        evaluator.close()


if __name__ == "__main__":
    main()
