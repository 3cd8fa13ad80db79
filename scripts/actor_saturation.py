"""Is a DDPG/TD3 run's actor saturated? For each run folder, the newest usable checkpoint's actor on the
states of a few seeded deterministic episodes: the share of action components beyond |a| = 0.99, the
median magnitude of each component's pre-tanh value, and each component's standard deviation across
states (0: the same action everywhere).

    python scripts/actor_saturation.py RUN_DIR [RUN_DIR ...] [--episodes 6] [--seed 1000]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch as th

from tsrl.agents.evaluation import load_run_policy
from tsrl.agents.factory import make_env


def saturation(run_dir: Path, episodes: int, seed: int) -> tuple[int, float, np.ndarray, np.ndarray]:
    """(env steps of the checkpoint, share of |a| > 0.99, median |pre-tanh| (k,), std of a (k,))."""
    cfg, model, normalizer, checkpoint = load_run_policy(run_dir)
    env = make_env(cfg)
    states = []
    for episode in range(episodes):
        obs, _ = env.reset(seed=seed + episode)
        done = False
        while not done:
            batch = {k: v[None] for k, v in obs.items()}
            if normalizer is not None:
                batch = normalizer.normalize_obs(batch)
            states.append(batch)
            action, _ = model.predict(batch, deterministic=True)
            obs, _, terminated, truncated, _ = env.step(action[0])
            done = terminated or truncated
    env.close()
    batch = {k: th.as_tensor(np.concatenate([s[k] for s in states])).float() for k in states[0]}
    actor = model.policy.actor
    with th.no_grad():
        pre_tanh = actor.mu[:-1](actor.extract_features(batch, actor.features_extractor))
    action = th.tanh(pre_tanh)
    share = float((action.abs() > 0.99).float().mean())
    return checkpoint.state.env_steps, share, pre_tanh.abs().median(0).values.numpy(), action.std(0).numpy()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dirs", type=Path, nargs="+")
    parser.add_argument("--episodes", type=int, default=6)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    print(
        f"{args.episodes} deterministic episodes per run, seeds {args.seed}..{args.seed + args.episodes - 1}\n"
    )
    print(
        "| run | env steps | share of abs(a) > 0.99 | median abs(pre-tanh) per component | std of a per component |"
    )
    print("| --- | ---: | ---: | --- | --- |")
    for run_dir in args.run_dirs:
        steps, share, pre, std = saturation(run_dir, args.episodes, args.seed)
        print(
            f"| {run_dir.name} | {steps:,} | {share:.3f} | {np.array2string(pre, precision=2)} "
            f"| {np.array2string(std, precision=3)} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
