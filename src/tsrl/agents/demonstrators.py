"""Demonstrators and recording: a built-in task's scripted solver (tsrl.envs.solvers) or a trained
run's policy, and `record_demos`, which runs one on seeded episodes and keeps the successful ones as
`Demonstrations` (tsrl.agents.demo_files)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

from ..envs.base import TaskEnv
from ..envs.keys import OBS_KEYS
from ..envs.solvers import Controller, solver_for
from ..exceptions import InvalidConfig, check_int
from .config import TASK_ACTION, TrainConfig
from .demo_files import ARRAYS, FORMAT, VERSION, Demonstrations, DemoSpec

#: Demonstration episode seeds are drawn from a stream of their own (apart from training and evaluation).
_DEMO_STREAM = 0xDE30


class PolicyDemonstrator:
    """A trained run's latest policy, deterministic, with its normaliser statistics."""

    def __init__(self, run_dir: Path | str):
        from .checkpoint import load_policy, usable_checkpoint
        from .factory import ALGO_CLASSES
        from .run_folder import NotARunFolder, load_config

        self.cfg = load_config(run_dir)
        checkpoint = usable_checkpoint(Path(run_dir), self.cfg.agent.normalize, for_training=False)
        if checkpoint is None:
            raise NotARunFolder(Path(run_dir), "no checkpoint yet")
        self.model, self.normalizer = load_policy(checkpoint, ALGO_CLASSES[self.cfg.agent.algo])
        self.name = f"policy:{Path(run_dir).resolve()}/{checkpoint.path.name}"

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """A policy remembers nothing between episodes."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        batch = {k: v[None] for k, v in obs.items()}
        if self.normalizer is not None:
            normalized = self.normalizer.normalize_obs(batch)
            assert isinstance(normalized, dict)  # a dict observation normalises to a dict
            batch = normalized
        action, _ = self.model.predict(batch, deterministic=True)
        return np.asarray(action[0], dtype=np.float32)


def demo_seeds(seed: int, n: int) -> list[int]:
    """Seeds of the first n demonstration episodes of recording seed `seed`."""
    return [int(s) for s in np.random.SeedSequence(entropy=seed, spawn_key=(_DEMO_STREAM,)).generate_state(n)]


def record_demos(
    env_id: str,
    episodes: int,
    obs: str = "",
    action: str = TASK_ACTION,
    policy: Path | str | None = None,
    seed: int = 0,
    keep_failed: bool = False,
    max_attempts: int | None = None,
) -> Demonstrations:
    """Records `episodes` demonstration episodes (successful ones only unless `keep_failed`).

    `obs` "" is the task's own observation (tsrl.agents.config.task_defaults). The demonstrator is
    the run folder `policy`'s policy (its env, obs and action then come from
    its config) or the built-in task's scripted solver (tsrl.envs.solvers.SOLVERS) in `action` (a
    built-in mode, or TASK_ACTION: the task's own). Episodes are attempted with `demo_seeds(seed, ...)`
    until enough are kept or `max_attempts` (default 10 x episodes) have run; the file says how many.
    """
    check_int("episodes", episodes, 0)
    from_run = PolicyDemonstrator(policy) if policy is not None else None
    if from_run is not None:
        env_id, obs, action = from_run.cfg.env_id, from_run.cfg.obs, from_run.cfg.action
    else:
        from .config import check_env_id

        check_env_id(env_id)
        try:
            solver = solver_for(env_id, None if action == TASK_ACTION else action)
        except InvalidConfig as err:
            raise InvalidConfig(f"{err}; pass --policy RUN_DIR to record a trained policy") from None
    run = TrainConfig(env_id=env_id, obs=obs, action=action)  # a registered id or a task file
    obs = run.obs  # "" resolved: the task's own
    env = gym.make(run.gym_id, **run.env_kwargs)
    base = env.unwrapped
    assert isinstance(base, TaskEnv)  # check_env_id: a tsrl environment
    demonstrator: Controller = from_run if from_run is not None else solver(base)
    spec = DemoSpec.of(env)
    assert env.spec is not None and env.spec.max_episode_steps is not None  # registered with a time limit
    t = int(env.spec.max_episode_steps)
    attempts = max_attempts if max_attempts is not None else 10 * episodes
    kept: list[dict[str, np.ndarray]] = []
    attempted = 0
    try:
        for episode_seed in demo_seeds(seed, attempts):
            if len(kept) >= episodes:
                break
            attempted += 1
            episode = _run_episode(env, demonstrator, episode_seed, t)
            if episode is not None and (keep_failed or episode["is_success"][-1]):
                kept.append(episode)
    finally:
        env.close()
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "env_id": spec.env_id,
        "obs": obs,
        "obs_spec": spec.obs_spec,
        "action": spec.action,
        "task_sha256": spec.task_sha256,
        "task_files": dict(spec.task_files) if spec.task_files is not None else None,
        "demonstrator": demonstrator.name,
        "tsrl_version": _tsrl_version(),
        "recording_seed": seed,
        "attempted": attempted,
        "kept": len(kept),
        "successful_only": not keep_failed,
    }
    if kept:
        arrays = {name: np.stack([e[name] for e in kept]) for name in ARRAYS}
    else:
        arrays = _empty_arrays(spec, t)
    return Demonstrations(**arrays, meta=meta)


def _run_episode(env: gym.Env, demonstrator: Controller, seed: int, t: int) -> dict[str, np.ndarray] | None:
    """One episode's arrays; None if it ended before its time limit (a physics blow-up)."""
    obs, _ = env.reset(seed=seed)
    demonstrator.reset(obs)
    trajectory = {key: [obs[key]] for key in OBS_KEYS}
    actions, rewards, success = [], [], []
    for step in range(t):
        action = np.clip(np.asarray(demonstrator.act(obs), dtype=np.float32), -1.0, 1.0)
        obs, reward, terminated, truncated, info = env.step(action)
        for key in OBS_KEYS:
            trajectory[key].append(obs[key])
        actions.append(action)
        rewards.append(reward)
        success.append(bool(info["is_success"]))
        if info.get("physics_unstable") or terminated or (truncated and step < t - 1):
            return None
    return {
        **{key: np.asarray(v, dtype=np.float64) for key, v in trajectory.items()},
        "actions": np.asarray(actions, dtype=np.float32),
        "rewards": np.asarray(rewards, dtype=np.float32),
        "is_success": np.asarray(success, dtype=bool),
        "seeds": np.asarray(seed, dtype=np.int64),
    }


def _empty_arrays(spec: DemoSpec, t: int) -> dict[str, np.ndarray]:
    return {
        "observation": np.zeros((0, t + 1, spec.obs_dim)),
        "achieved_goal": np.zeros((0, t + 1, spec.goal_dim)),
        "desired_goal": np.zeros((0, t + 1, spec.goal_dim)),
        "actions": np.zeros((0, t, spec.action_dim), dtype=np.float32),
        "rewards": np.zeros((0, t), dtype=np.float32),
        "is_success": np.zeros((0, t), dtype=bool),
        "seeds": np.zeros(0, dtype=np.int64),
    }


def _tsrl_version() -> str:
    from .. import __version__

    return __version__
