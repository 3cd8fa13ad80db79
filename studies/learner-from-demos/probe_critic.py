"""Probe (README, "The stack's failures"): does the fast learner's critic tell the episodes its policy
will win from those it will lose?

For a run's checkpoint at the given env steps, the policy as it acts on the run's own evaluation seeds;
at 0, 20, 40 and 60 % of each episode's steps, the smaller twin head of the critic on the action taken,
and the AUC of that value against the episode's success at its last step (the chance that a won
episode's value is above a lost one's; 0.5: the critic does not tell them apart). Every episode runs to
the time limit, so the policy's batch row i is episode i.

    python studies/learner-from-demos/probe_critic.py RUN_DIR --at 5000 25000 [--episodes 100]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from probe_failures import load_run  # type: ignore[import-not-found]

from tsrl.agents.reference import heads

SHARES = (0.0, 0.2, 0.4, 0.6)
"""Where in the episode the values are compared (shares of its steps)."""


def auc(values: np.ndarray, won: np.ndarray) -> float:
    """P(value of a won episode > value of a lost one), ties counted half; nan without both kinds."""
    wins, losses = values[won], values[~won]
    if len(wins) == 0 or len(losses) == 0:
        return float("nan")
    greater = (wins[:, None] > losses[None, :]).mean()
    ties = (wins[:, None] == losses[None, :]).mean()
    return float(greater + 0.5 * ties)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--at", type=int, nargs="+", required=True, help="checkpoints' env steps")
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()
    print(
        "| env steps | success | "
        + " | ".join(f"AUC of Q at {share:.0%} of the episode" for share in SHARES)
        + " |"
    )
    print("| ---: | ---: | " + " | ".join("---:" for _ in SHARES) + " |")
    for at in args.at:
        evaluator, model, normalizer, _ = load_run(args.run_dir, args.episodes, at)
        policy = model.policy
        acting = policy._predict
        values: list[np.ndarray] = []

        def act(
            obs: Any,
            deterministic: bool = False,
            acting: Any = acting,
            values: list = values,
            critic: Any = policy.critic,
        ) -> th.Tensor:
            action = acting(obs, deterministic)
            assert action.shape[0] == args.episodes, "an episode ended before the time limit"
            values.append(heads(critic, obs, action).min(dim=1).values.numpy())
            return action

        policy._predict = act  # type: ignore[method-assign]
        success = np.zeros(args.episodes, dtype=bool)

        def record(i: int, info: dict[str, Any], success: np.ndarray = success) -> None:
            success[i] = bool(info["is_success"])  # the last step's stays

        with th.no_grad():
            evaluator.evaluate(model, normalizer, on_step=record)
        evaluator.close()
        print(
            f"| {at:,} | {success.mean():.2f} | "
            + " | ".join(f"{auc(values[int(share * len(values))], success):.2f}" for share in SHARES)
            + " |",
            flush=True,
        )


if __name__ == "__main__":
    main()
