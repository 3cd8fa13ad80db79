"""A probe of the fast learner's choice (tsrl.agents.reference): per checkpoint of one run, the success
of the policy as it acts (the choice), of its actor alone and of its reference clone alone, on the
run's own 100 evaluation seeds, and the share of steps where the choice took the actor's action.

    python studies/learner-from-demos/probe_choice.py RUN_DIR [--episodes 100]

Prints one table row per checkpoint. A probe, not a screen: it looks for the cause of a drop.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import torch as th

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import reference as reference_module
from tsrl.agents.checkpoint import load_policy, verify_checkpoint
from tsrl.agents.evaluation import Evaluator, eval_seeds
from tsrl.agents.factory import ALGO_CLASSES
from tsrl.agents.run_folder import checkpoint_dirs, load_config


class ActorShare:
    """Counts, over calls of tsrl.agents.reference.choose from the policy's _predict, the rows where
    the actor's action was taken."""

    def __init__(self) -> None:
        self.actor = self.rows = 0
        self.choose = reference_module.choose

    def __call__(
        self, critic: Any, obs: Any, actor_actions: th.Tensor, reference_actions: th.Tensor
    ) -> th.Tensor:
        chosen = self.choose(critic, obs, actor_actions, reference_actions)
        self.actor += int((chosen == actor_actions).all(dim=1).logical_and(
            (actor_actions != reference_actions).any(dim=1)).sum())  # fmt: skip
        self.rows += int(chosen.shape[0])
        return chosen


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    cfg = load_config(args.run_dir)
    evaluator = Evaluator(cfg, eval_seeds(cfg.seed, args.episodes))
    print("| env steps | choice | actor alone | clone alone | actor's share of the choice's steps |")
    print("| ---: | ---: | ---: | ---: | ---: |")
    for directory in checkpoint_dirs(args.run_dir):
        checkpoint = verify_checkpoint(directory, cfg.agent.normalize, for_training=False)
        model, normalizer = load_policy(checkpoint, ALGO_CLASSES[cfg.agent.algo])
        policy = model.policy
        share = ActorShare()
        reference_module.choose = share
        try:
            choice = evaluator.evaluate(model, normalizer).success_rate
        finally:
            reference_module.choose = share.choose
        alone = {}
        for name in ("actor", "reference"):
            net = getattr(policy, name)
            policy._predict = lambda obs, deterministic=False, net=net: net(obs)  # type: ignore[method-assign]
            alone[name] = evaluator.evaluate(model, normalizer).success_rate
        print(
            f"| {checkpoint.state.env_steps:,} | {choice:.2f} | {alone['actor']:.2f} | {alone['reference']:.2f} | "
            f"{share.actor / max(share.rows, 1):.2f} |",
            flush=True,
        )
    evaluator.close()


if __name__ == "__main__":
    main()
