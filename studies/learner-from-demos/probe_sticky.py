"""Does the choice act better when it keeps its proposal? For the newest checkpoint of each run, the
choice between actor and clone (tsrl.agents.reference) on the run's own evaluation seeds, as it acts
(per step, the proposal whose smaller critic head is higher) and with a margin `delta` [in the
critic's units]: the proposal that acted at the last step keeps acting unless the other's smaller head
is higher by more than delta (hysteresis). delta 0 is the choice as it acts (but for exact ties).

    python studies/learner-from-demos/probe_sticky.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--deltas 0 0.1 0.3 1]

Per run and delta: success, proposal switches and finger-command sign changes per episode (the last
action component), and for delta 0 the quantiles of |min-head difference| between the proposals.
A probe, not a screen: the policy's training is untouched; only how it acts changes.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from probe_failures import load_run  # type: ignore[import-not-found]

from tsrl.agents.reference import heads

ACTOR, CLONE = 0, 1


def proposals_and_values(policy: Any, batch: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(2, n, k) the actor's and the clone's actions, (2, n) their smaller critic heads, on a normalised
    observation batch."""
    obs, _ = policy.obs_to_tensor(batch)
    with th.no_grad():
        actions = th.stack((policy.actor(obs), policy.reference(obs)))
        low = th.stack([heads(policy.critic, obs, a).min(dim=1).values for a in actions])
    return actions.numpy(), low.numpy()


def run_episodes(evaluator: Any, model: Any, normalizer: Any, delta: float) -> dict[str, Any]:
    """Every evaluation seed's episode in lockstep (as tsrl's Evaluator steps them), acting by the
    sticky choice with margin `delta`; success, switches and finger flips per episode, |differences|."""
    envs, seeds = evaluator.envs, evaluator.seeds
    observations = [env.reset(seed=s)[0] for env, s in zip(envs, seeds, strict=True)]
    source = np.full(len(envs), -1)
    switches, flips = np.zeros(len(envs)), np.zeros(len(envs))
    last_finger = np.zeros(len(envs))
    success = np.zeros(len(envs), dtype=bool)
    differences: list[np.ndarray] = []
    active = list(range(len(envs)))
    while active:
        batch = {key: np.stack([observations[i][key] for i in active]) for key in observations[0]}
        if normalizer is not None:
            batch = normalizer.normalize_obs(batch)
        actions, low = proposals_and_values(model.policy, batch)
        differences.append(np.abs(low[CLONE] - low[ACTOR]))
        still = []
        for row, i in enumerate(active):
            prev = source[i]
            if prev == CLONE:
                now = ACTOR if low[ACTOR, row] > low[CLONE, row] + delta else CLONE
            elif prev == ACTOR:
                now = CLONE if low[CLONE, row] > low[ACTOR, row] + delta else ACTOR
            else:
                now = CLONE if low[CLONE, row] > low[ACTOR, row] else ACTOR
            switches[i] += prev >= 0 and now != prev
            source[i] = now
            action = actions[now, row]
            finger = np.sign(action[-1])
            flips[i] += last_finger[i] != 0 and finger != 0 and finger != last_finger[i]
            last_finger[i] = finger if finger != 0 else last_finger[i]
            observations[i], _, terminated, truncated, info = envs[i].step(action)
            if terminated or truncated:
                success[i] = bool(info.get("is_success", False))
            else:
                still.append(i)
        active = still
    return {
        "success": float(success.mean()),
        "switches": float(switches.mean()),
        "flips": float(flips.mean()),
        "differences": np.concatenate(differences),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--deltas", type=float, nargs="+", default=[0.0, 0.1, 0.3, 1.0])
    args = parser.parse_args()
    print("| run | env steps | delta | success | switches per episode | finger flips per episode |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for run_dir in args.run_dirs:
        evaluator, model, normalizer, checkpoint = load_run(run_dir, args.episodes)
        spread = None
        for delta in args.deltas:
            result = run_episodes(evaluator, model, normalizer, delta)
            if delta == 0:
                spread = np.quantile(result["differences"], [0.25, 0.5, 0.75, 0.9])
            print(
                f"| {run_dir.name[-30:]} | {checkpoint.state.env_steps:,} | {delta:g} | "
                f"{result['success']:.2f} | {result['switches']:.1f} | {result['flips']:.1f} |",
                flush=True,
            )
        evaluator.close()
        if spread is not None:
            print(f"\n|min-head difference| quantiles 25/50/75/90 %: {np.round(spread, 3).tolist()}\n")


if __name__ == "__main__":
    main()
