"""Probe (README, "The stack's failures"): does BC on the stack climb when the scripted solver's
demonstrations are recorded with noise injected into the executed actions (DART, Laskey et al. 2017)?

The solver acts closed-loop on every state, so an episode run with Gaussian noise (std `--noise` in
action units, on the position dimensions; the gripper's command as the solver gives it) visits states
off the solver's own path, each labelled with the solver's clean action there. The successful episodes
are kept (the file's `actions` are these labels, not the executed actions) and BC is trained on them
as pre-registration 1's BC (run.py's bc arm); its row goes to data/probes.csv as `dartN-sS` (N
demonstrations, noise S).

    python studies/learner-from-demos/probe_dart.py PandaStack-v0 --demos 100 --noise 0.3
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
import run

from tsrl.agents.config import TrainConfig
from tsrl.agents.demo_files import ARRAYS, Demonstrations, load_demos, save_demos
from tsrl.agents.demonstrators import demo_seeds
from tsrl.envs.keys import OBS_KEYS
from tsrl.envs.solvers import solver_for


def record_noisy(task: str, n: int, noise: float, seed: int) -> list[dict[str, np.ndarray]]:
    """`n` successful episodes of the solver with noise on the executed position dimensions."""
    cfg = TrainConfig(env_id=f"tsrl/{task}")
    env = gym.make(cfg.gym_id, **cfg.env_kwargs)
    solver = solver_for(cfg.env_id)(env.unwrapped)
    assert env.spec is not None and env.spec.max_episode_steps is not None
    t = int(env.spec.max_episode_steps)
    rng = np.random.default_rng(seed)
    kept: list[dict[str, np.ndarray]] = []
    attempted = 0
    for episode_seed in demo_seeds(seed, 20 * n):
        if len(kept) == n:
            break
        attempted += 1
        obs, _ = env.reset(seed=episode_seed)
        solver.reset(obs)
        trajectory = {key: [obs[key]] for key in OBS_KEYS}
        labels, rewards, success = [], [], []
        for _ in range(t):
            label = np.clip(np.asarray(solver.act(obs), dtype=np.float32), -1.0, 1.0)
            executed = label.copy()
            executed[:-1] += rng.normal(0.0, noise, size=label.shape[0] - 1).astype(np.float32)
            obs, reward, _, _, info = env.step(np.clip(executed, -1.0, 1.0))
            for key in OBS_KEYS:
                trajectory[key].append(obs[key])
            labels.append(label)
            rewards.append(reward)
            success.append(bool(info["is_success"]))
        if success[-1]:
            kept.append(
                {
                    **{key: np.asarray(v, dtype=np.float64) for key, v in trajectory.items()},
                    "actions": np.asarray(labels, dtype=np.float32),
                    "rewards": np.asarray(rewards, dtype=np.float32),
                    "is_success": np.asarray(success, dtype=bool),
                    "seeds": np.asarray(episode_seed, dtype=np.int64),
                }
            )
    env.close()
    print(f"noise {noise}: kept {len(kept)} of {attempted}", flush=True)
    return kept


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task", choices=sorted(run.BUDGETS))
    parser.add_argument("--demos", type=int, default=100)
    parser.add_argument("--noise", type=float, default=0.3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("results/learner-from-demos"))
    args = parser.parse_args()
    clean = load_demos(run.demo_file(args.out, args.task, args.demos))  # its meta: same env and layout
    kept = record_noisy(args.task, args.demos, args.noise, seed=0)
    arrays = {name: np.stack([e[name] for e in kept]) for name in ARRAYS}
    meta = dict(clean.meta) | {
        "demonstrator": f"{clean.meta['demonstrator']}+dart{args.noise}",
        "kept": len(kept),
    }
    arm = f"dart{args.demos}-s{args.noise}"
    path = args.out / "demos" / f"{args.task}-{arm}.npz"
    save_demos(Demonstrations(**arrays, meta=meta), path)
    run.bc_probe(arm, args.task, args.seed, path, args.out)


if __name__ == "__main__":
    main()
