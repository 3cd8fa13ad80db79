"""Deterministic evaluation of a policy on seeded episodes: success rate and final distance."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from .config import TrainConfig
from .factory import make_env

#: Evaluation seeds are drawn from a stream of their own, apart from training's episode seeds.
_EVAL_STREAM = 0xE7A1


@dataclass(frozen=True)
class EvalResult:
    success_rate: float
    """Fraction of episodes whose last step has info["is_success"]."""
    mean_final_distance: float
    """Mean of info["distance"] at the last step [m] (NaN if the env does not report it)."""
    episodes: int


def eval_seeds(seed: int, n: int) -> list[int]:
    """The seeds of a run's n evaluation episodes: fixed for the run, different across run seeds."""
    return [int(s) for s in np.random.SeedSequence(entropy=seed, spawn_key=(_EVAL_STREAM,)).generate_state(n)]


class Evaluator:
    """Runs `len(seeds)` episodes side by side (one batched policy call per step), deterministically.

    Owns its environments: call close() when done.
    """

    def __init__(self, cfg: TrainConfig, seeds: list[int]):
        self.seeds = list(seeds)
        self.envs: list[gym.Env] = [make_env(cfg) for _ in self.seeds]

    def evaluate(self, model: BaseAlgorithm, normalizer: VecNormalize | None) -> EvalResult:
        observations = [env.reset(seed=s)[0] for env, s in zip(self.envs, self.seeds, strict=True)]
        active = list(range(len(self.envs)))
        success = np.zeros(len(self.envs), dtype=bool)
        distance = np.full(len(self.envs), np.nan)
        while active:
            batch = {key: np.stack([observations[i][key] for i in active]) for key in observations[0]}
            if normalizer is not None:
                batch = normalizer.normalize_obs(batch)
            actions, _ = model.predict(batch, deterministic=True)
            still = []
            for i, action in zip(active, actions, strict=True):
                observations[i], _, terminated, truncated, info = self.envs[i].step(action)
                if terminated or truncated:
                    success[i] = bool(info.get("is_success", False))
                    distance[i] = float(info.get("distance", np.nan))
                else:
                    still.append(i)
            active = still
        mean_distance = float(np.mean(distance)) if np.all(np.isfinite(distance)) else float("nan")
        return EvalResult(float(np.mean(success)), mean_distance, len(self.envs))

    def close(self) -> None:
        for env in self.envs:
            env.close()
