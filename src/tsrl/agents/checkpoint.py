"""Checkpoints of a run: model, replay buffer, normaliser statistics, counters and RNG states.

A checkpoint is a folder `checkpoints/step_<env steps>/`, written whole into a temporary folder and
renamed into place (atomic), so a run killed at any moment (SIGKILL included) leaves only complete
checkpoints. The latest complete one is the one with the most env steps; older ones are removed once
a newer one is in place. Checkpoints are only taken between updates, at an episode boundary, so a
resumed run starts a fresh episode with nothing half-stored.
"""

from __future__ import annotations

import json
import os
import pickle
import random
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

CHECKPOINTS = "checkpoints"
MODEL = "model.zip"
REPLAY_BUFFER = "replay_buffer.pkl"
NORMALIZER = "vecnormalize.pkl"
RNG = "rng.pkl"
STATE = "state.json"


@dataclass(frozen=True)
class RunState:
    """Counters of a run at a checkpoint."""

    env_steps: int
    episodes: int
    wall_time_s: float
    """Training wall time up to the checkpoint, evaluations included, summed over resumed sessions."""
    next_eval: int
    next_checkpoint: int
    eval_time_s: float = 0.0
    """Part of wall_time_s spent in evaluations."""


def checkpoint_dirs(run_dir: Path | str) -> list[Path]:
    """Complete checkpoints of a run, oldest first."""
    root = Path(run_dir) / CHECKPOINTS
    if not root.is_dir():
        return []
    dirs = [p for p in root.glob("step_*") if p.is_dir() and (p / STATE).is_file()]
    return sorted(dirs, key=lambda p: int(p.name.removeprefix("step_")))


def latest_checkpoint(run_dir: Path | str) -> Path | None:
    dirs = checkpoint_dirs(run_dir)
    return dirs[-1] if dirs else None


def save_checkpoint(
    run_dir: Path, model: OffPolicyAlgorithm, normalizer: VecNormalize | None, state: RunState
) -> Path:
    """Writes a checkpoint atomically and removes the older ones; returns its folder."""
    root = run_dir / CHECKPOINTS
    root.mkdir(parents=True, exist_ok=True)
    final = root / f"step_{state.env_steps:010d}"
    if (final / STATE).is_file():  # this very state is already saved (e.g. a stop right after resuming)
        return final
    tmp = root / f".tmp-step_{state.env_steps:010d}-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir()
    model.save(tmp / MODEL)
    with open(tmp / REPLAY_BUFFER, "wb") as f:
        pickle.dump(model.replay_buffer, f, protocol=pickle.HIGHEST_PROTOCOL)
    if normalizer is not None:
        with open(tmp / NORMALIZER, "wb") as f:
            pickle.dump(normalizer, f, protocol=pickle.HIGHEST_PROTOCOL)
    with open(tmp / RNG, "wb") as f:
        pickle.dump(_rng_state(model), f, protocol=pickle.HIGHEST_PROTOCOL)
    (tmp / STATE).write_text(json.dumps(state.__dict__, indent=2) + "\n")  # last: marks it complete
    shutil.rmtree(final, ignore_errors=True)
    os.replace(tmp, final)
    for old in root.iterdir():
        if old != final and (old.name.startswith("step_") or old.name.startswith(".tmp-")):
            shutil.rmtree(old, ignore_errors=True)
    return final


def read_state(checkpoint: Path) -> RunState:
    return RunState(**json.loads((checkpoint / STATE).read_text()))


def load_checkpoint(
    checkpoint: Path, algo_class: type[OffPolicyAlgorithm], env: VecEnv, normalizer: VecNormalize | None
) -> tuple[OffPolicyAlgorithm, RunState]:
    """The model of `checkpoint` on `env`, with its replay buffer, normaliser statistics and RNG states."""
    model = algo_class.load(checkpoint / MODEL, env=env, device="cpu")
    model.load_replay_buffer(checkpoint / REPLAY_BUFFER, truncate_last_traj=False)
    if normalizer is not None and (checkpoint / NORMALIZER).is_file():
        with open(checkpoint / NORMALIZER, "rb") as f:
            saved: VecNormalize = pickle.load(f)
        normalizer.obs_rms = saved.obs_rms
        normalizer.ret_rms = saved.ret_rms
    with open(checkpoint / RNG, "rb") as f:
        _set_rng_state(model, pickle.load(f))
    state = read_state(checkpoint)
    model.num_timesteps = state.env_steps
    model._episode_num = state.episodes
    return model, state


def load_policy(checkpoint: Path, algo_class: type[OffPolicyAlgorithm]) -> tuple[Any, VecNormalize | None]:
    """Model (without env or replay buffer) and normaliser of a checkpoint, for evaluation and rendering."""
    # No env and a token replay buffer: HER's buffer needs an env, and evaluation needs no buffer.
    no_buffer = {"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1}
    model = algo_class.load(checkpoint / MODEL, device="cpu", custom_objects=no_buffer)
    normalizer = None
    if (checkpoint / NORMALIZER).is_file():
        with open(checkpoint / NORMALIZER, "rb") as f:
            normalizer = pickle.load(f)
        normalizer.training = False
    return model, normalizer


def _rng_state(model: OffPolicyAlgorithm) -> dict[str, Any]:
    return {
        "python": random.getstate(),
        "numpy": np.random.get_state(),
        "torch": th.get_rng_state(),
        "action_space": model.action_space.np_random.bit_generator.state,
    }


def _set_rng_state(model: OffPolicyAlgorithm, state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    th.set_rng_state(state["torch"])
    model.action_space.np_random.bit_generator.state = state["action_space"]
