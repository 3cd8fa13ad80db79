"""Demonstrators and recording: the scripted reach and pick-and-place controllers, a trained run's
policy, and `record_demos`, which runs one on seeded episodes and keeps the successful ones as
`Demonstrations` (tsrl.agents.demo_files)."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol

import gymnasium as gym
import numpy as np

from ..envs.actions import ACTION_PRESETS
from ..envs.keys import OBS_KEYS
from ..exceptions import InvalidConfig, check_int
from .config import TrainConfig
from .demo_files import ARRAYS, FORMAT, VERSION, Demonstrations, DemoSpec

#: Demonstration episode seeds are drawn from a stream of their own (apart from training and evaluation).
_DEMO_STREAM = 0xDE30


class Demonstrator(Protocol):
    """Chooses the actions of demonstration episodes."""

    name: str

    def reset(self, seed: int) -> None:
        """Called after the recording env's reset(seed=seed)."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The action (k,) for the recording env's observation; the recorder steps with exactly it."""

    def close(self) -> None:
        """Releases what the demonstrator holds (environments)."""


#: Action modes the scripted demonstrators act in; in taskspace_orient they hold the start orientation.
SCRIPTED_ACTIONS: tuple[str, ...] = ("taskspace", "taskspace_orient")


class _ShadowController:
    """A controller that reads positions from a second env of the same id, stepped in lockstep.

    The shadow env observes the positions the controller needs (its own spec); it is reset with the
    recording env's seed and stepped with the same actions, so its state is the recording env's
    (the environments are deterministic; each step checks that both goals agree).
    """

    spec: str = ""

    def __init__(self, env_id: str, action: str):
        if action not in SCRIPTED_ACTIONS:
            raise InvalidConfig(
                f"the scripted demonstrators act in action modes {', '.join(SCRIPTED_ACTIONS)}; got {action!r}"
            )
        # Parts after the TCP position (taskspace_orient's scalar products, absolute parts) are held at
        # their start values: the shadow env observes them; their action is (y - center) / half_range.
        self.held = ACTION_PRESETS[action].parts[1:]
        spec = ", ".join([self.spec, *(part.map for part in self.held)])
        self.env = gym.make(env_id, obs=spec, action=action)
        self.slices = self.env.unwrapped.observation_structure
        self.max_step = float(self.env.unwrapped.task.action_spec.parts[0].step)
        self.obs: dict[str, np.ndarray] = {}
        self.hold = np.zeros(0)

    def reset(self, seed: int) -> None:
        self.obs, _ = self.env.reset(seed=seed)
        y = self.obs["observation"]
        held = [(y[self.slices[p.map]] - np.asarray(p.center)) / np.asarray(p.half_range) for p in self.held]
        self.hold = np.concatenate([np.zeros(0), *held])

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        for key in ("achieved_goal", "desired_goal"):
            if not np.array_equal(obs[key], self.obs[key]):
                raise RuntimeError(f"{self.name}: its shadow env diverged from the recording env ({key})")
        positions = self.obs["observation"]
        action = self.control({name: positions[s] for name, s in self.slices.items()})
        action = np.concatenate([action[:3], self.hold, action[3:]])  # position, held parts, suction
        action = action.astype(np.float32)
        self.obs, *_ = self.env.step(action)
        return action

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        raise NotImplementedError

    def close(self) -> None:
        self.env.close()


class ReachController(_ShadowController):
    """Reach: a straight line to the goal at up to the full TCP step; the env's IK turns it into joints."""

    name = "scripted-reach"
    spec = "position(tcp), position(target)"

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        return np.clip((y["position(target)"] - y["position(tcp)"]) / self.max_step, -1.0, 1.0)


class ScriptedPickPlace(_ShadowController):
    """Pick-and-place: above the box, descend, suction on, lift, carry, release (goals on the table)
    or hold (in the air). Succeeds on >= 95 of 100 seeded episodes (tests/envs)."""

    name = "scripted-pick-place"
    spec = "position(tcp), position(box), position(target)"
    HOVER = 0.10  # m above the box top before descending
    GRIP_DEPTH = 0.004  # m the cup target goes below the box top, to press the cup onto it
    CARRY_SPEED = 0.6  # fraction of the largest TCP step while the box hangs on the cup

    def __init__(self, env_id: str, action: str):
        super().__init__(env_id, action)
        self.box_half_size = float(self.env.unwrapped.model.geom("box").size[0])

    def reset(self, seed: int) -> None:
        super().reset(seed)
        self.phase = "approach"

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        half = self.box_half_size
        tcp, box, goal = y["position(tcp)"], y["position(box)"], y["position(target)"]
        box_top = box + [0.0, 0.0, half]
        suction = -1.0
        if self.phase == "approach":
            target = box_top + [0.0, 0.0, self.HOVER]
            if np.linalg.norm(tcp - target) < 0.01:
                self.phase = "descend"
        if self.phase == "descend":
            target = box_top - [0.0, 0.0, self.GRIP_DEPTH]
            if tcp[2] < box_top[2] + 0.003:
                self.phase = "lift"
        if self.phase == "lift":
            suction = 1.0
            target = np.array([*box_top[:2], max(goal[2], half) + half + 0.08])
            if tcp[2] > target[2] - 0.02:
                self.phase = "carry"
        if self.phase == "carry":
            suction = 1.0
            target = goal + [0.0, 0.0, half]
            if goal[2] < 1.5 * half and np.linalg.norm(box - goal) < 0.01:
                self.phase = "release"
        if self.phase == "release":
            target = goal + [0.0, 0.0, half + 0.03]
        speed = self.CARRY_SPEED if self.phase in ("lift", "carry") else 1.0
        return np.append(np.clip((target - tcp) / self.max_step, -speed, speed), suction)


#: The scripted demonstrator of each environment.
SCRIPTED: dict[str, type[_ShadowController]] = {
    "tsrl/UR5eReach-v0": ReachController,
    "tsrl/UR5ePickPlace-v0": ScriptedPickPlace,
    "tsrl/PandaReach-v0": ReachController,
    "tsrl/PandaPickPlace-v0": ScriptedPickPlace,
}


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

    def reset(self, seed: int) -> None:
        pass

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        batch = {k: v[None] for k, v in obs.items()}
        if self.normalizer is not None:
            batch = self.normalizer.normalize_obs(batch)
        action, _ = self.model.predict(batch, deterministic=True)
        return np.asarray(action[0], dtype=np.float32)

    def close(self) -> None:
        pass


def demo_seeds(seed: int, n: int) -> list[int]:
    """Seeds of the first n demonstration episodes of recording seed `seed`."""
    return [int(s) for s in np.random.SeedSequence(entropy=seed, spawn_key=(_DEMO_STREAM,)).generate_state(n)]


def record_demos(
    env_id: str,
    episodes: int,
    obs: str = "fs1",
    action: str = "taskspace",
    policy: Path | str | None = None,
    seed: int = 0,
    keep_failed: bool = False,
    max_attempts: int | None = None,
) -> Demonstrations:
    """Records `episodes` demonstration episodes (successful ones only unless `keep_failed`).

    The demonstrator is the run folder `policy`'s policy (its env, obs and action then come from
    its config) or the env's scripted controller. Episodes are attempted with `demo_seeds(seed, ...)`
    until enough are kept or `max_attempts` (default 10 x episodes) have run; the file says how many.
    """
    check_int("episodes", episodes, 0)
    demonstrator: Demonstrator
    if policy is not None:
        from_run = PolicyDemonstrator(policy)
        env_id, obs, action = from_run.cfg.env_id, from_run.cfg.obs, from_run.cfg.action
        demonstrator = from_run
    else:
        from .config import check_env_id

        check_env_id(env_id)
        if env_id not in SCRIPTED:
            raise InvalidConfig(
                f"no scripted demonstrator for {env_id!r} (scripted: {', '.join(SCRIPTED)}); "
                "pass --policy RUN_DIR to record a trained policy"
            )
        demonstrator = SCRIPTED[env_id](env_id, action)
    run = TrainConfig(env_id=env_id, obs=obs, action=action)  # a registered id or a task file
    env = gym.make(run.gym_id, **run.env_kwargs)
    spec = DemoSpec.of(env)
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
        demonstrator.close()
    meta = {
        "format": FORMAT,
        "version": VERSION,
        "env_id": spec.env_id,
        "obs": obs,
        "obs_spec": spec.obs_spec,
        "action": spec.action,
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


def _run_episode(env: gym.Env, demonstrator: Demonstrator, seed: int, t: int) -> dict[str, np.ndarray] | None:
    """One episode's arrays; None if it ended before its time limit (a physics blow-up)."""
    obs, _ = env.reset(seed=seed)
    demonstrator.reset(seed)
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
        "seeds": np.int64(seed),
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
