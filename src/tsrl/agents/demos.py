"""Learning from demonstrations (Nair et al. 2018, "Overcoming Exploration in RL with Demonstrations").

Three parts:

- **Demonstrations as data.** `record_demos` runs a demonstrator (the scripted pick-and-place
  controller, the straight-line reach controller, or a trained run folder's policy) on seeded episodes
  and keeps the successful ones; `save_demos` / `load_demos` write and read them as one `.npz` file
  (format below), checked on load: a missing, truncated or corrupt file, NaN/inf, or a file from
  another environment, observation spec or action mode is one `DemoFileError` that says what differs.
- **A demonstration buffer.** `DemoReplayBuffer` is the run's `FeatureHerReplayBuffer` with a second
  one beside it that holds the demonstration episodes, HER-relabelled the same feature-aware way;
  each minibatch draws `batch_share` of its rows from it (the last rows of the batch).
- **A Q-filtered behaviour-cloning loss.** `attach_bc_loss` registers a step pre-hook on the actor's
  optimizer: stable-baselines3 runs `zero_grad(); actor_loss.backward(); step()`, and the hook
  back-propagates `bc_weight * L_BC` on the demonstration rows of the batch just sampled before the
  step, so the step follows grad(actor_loss + bc_weight * L_BC) without copying any `train()`. It works
  the same for DDPG, TD3 (whose delayed actor step uses the batch of its own gradient step) and SAC
  (cloning the deterministic action tanh(mean)).

    L_BC = 1/n_demo * sum_i 1[Q(s_i, a_i) > Q(s_i, pi(s_i))] * ||pi(s_i) - a_i||^2

Q is the critic's first head (the one DDPG's and TD3's actor maximise). Without `q_filter` every
demonstration row counts.

## File format (version 1)
One `np.savez_compressed` archive, readable with `np.load(path)` (no pickles). N episodes of T steps:

| array | shape | dtype | meaning |
| --- | --- | --- | --- |
| meta | () | str | JSON: format "tsrl-demos", version, env_id, obs (as given), obs_spec (the env's), action (mode), demonstrator, tsrl_version, attempted (episodes run), kept |
| observation | (N, T+1, d) | float64 | `observation` at reset and after each step |
| achieved_goal | (N, T+1, g) | float64 | |
| desired_goal | (N, T+1, g) | float64 | |
| actions | (N, T, k) | float32 | actions executed, in [-1, 1] |
| rewards | (N, T) | float32 | env rewards |
| is_success | (N, T) | bool | `info["is_success"]` after each step |
| seeds | (N,) | int64 | `env.reset(seed=...)` of each episode |

Every episode has the environment's full length (T steps, ended by its time limit); an episode cut
short (a physics blow-up) is dropped while recording.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3 import SAC
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.type_aliases import DictReplayBufferSamples
from stable_baselines3.common.vec_env import VecEnv, VecNormalize
from torch.utils.hooks import RemovableHandle

from ..envs.actions import ACTION_PRESETS
from ..exceptions import InvalidConfig, TsrlError
from .config import DemoConfig, TrainConfig
from .her import FeatureHerReplayBuffer

FORMAT = "tsrl-demos"
VERSION = 1
#: Arrays of a demonstration file besides `meta`.
ARRAYS: tuple[str, ...] = (
    "observation",
    "achieved_goal",
    "desired_goal",
    "actions",
    "rewards",
    "is_success",
    "seeds",
)
OBS_KEYS: tuple[str, ...] = ("observation", "achieved_goal", "desired_goal")
#: A run folder's record of the demonstrations it trained with (path, sha256, counts).
DEMOS_RECORD = "demos.json"
#: Demonstration episode seeds are drawn from a stream of their own (apart from training and evaluation).
_DEMO_STREAM = 0xDE30


class DemoFileError(TsrlError):
    """A demonstration file that is missing, unreadable, inconsistent or for another environment."""

    def __init__(self, path: Path | str, why: str):
        super().__init__(f"demonstration file {path}: {why}")


# -- data ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DemoSpec:
    """What a demonstration must match to be used on an environment."""

    env_id: str
    obs_spec: str
    action: str
    obs_dim: int
    goal_dim: int
    action_dim: int

    @classmethod
    def of(cls, env: gym.Env) -> DemoSpec:
        """The spec of a tsrl environment (made with gym.make)."""
        base = env.unwrapped
        if not hasattr(base, "obs_spec") or not hasattr(base, "relabel"):
            raise InvalidConfig(f"{env.spec.id if env.spec else env}: demonstrations need a tsrl environment")
        space = base.observation_space
        return cls(
            env_id=env.spec.id if env.spec is not None else type(base).__name__,
            obs_spec=base.obs_spec,
            action=base.action_mode,
            obs_dim=int(space["observation"].shape[0]),
            goal_dim=int(space["desired_goal"].shape[0]),
            action_dim=int(base.action_space.shape[0]),
        )


@dataclass(frozen=True)
class Demonstrations:
    """N demonstration episodes of T steps (shapes in the module docstring) and their metadata."""

    observation: np.ndarray
    achieved_goal: np.ndarray
    desired_goal: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    is_success: np.ndarray
    seeds: np.ndarray
    meta: dict[str, Any]

    @property
    def n_episodes(self) -> int:
        return int(self.actions.shape[0])

    @property
    def episode_steps(self) -> int:
        return int(self.actions.shape[1])

    @property
    def n_transitions(self) -> int:
        return self.n_episodes * self.episode_steps

    @property
    def spec(self) -> DemoSpec:
        m = self.meta
        return DemoSpec(
            m["env_id"],
            m["obs_spec"],
            m["action"],
            self.observation.shape[2],
            self.desired_goal.shape[2],
            self.actions.shape[2],
        )


def save_demos(demos: Demonstrations, path: Path | str) -> Path:
    """Writes `demos` to `path` (.npz; written whole, then renamed into place). Returns the path."""
    path = Path(path)
    if path.suffix != ".npz":
        raise InvalidConfig(f"a demonstration file ends in .npz; got {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.npz")
    arrays = {name: getattr(demos, name) for name in ARRAYS}
    np.savez_compressed(tmp, meta=np.array(json.dumps(demos.meta)), **arrays)
    os.replace(tmp, path)
    return path


def load_demos(path: Path | str, expect: DemoSpec | None = None) -> Demonstrations:
    """Reads and checks a demonstration file; with `expect`, it must match that environment spec.

    Raises DemoFileError (missing, truncated or corrupt, another format, inconsistent shapes, NaN/inf,
    actions outside [-1, 1], or a spec that differs from `expect`, naming the differences).
    """
    path = Path(path)
    if not path.is_file():
        raise DemoFileError(path, "no such file")
    try:
        with np.load(path, allow_pickle=False) as f:
            missing = [name for name in ("meta", *ARRAYS) if name not in f.files]
            if missing:
                raise DemoFileError(path, f"not a tsrl demonstration file: no {', '.join(missing)}")
            arrays = {name: f[name] for name in ARRAYS}
            meta_text = str(f["meta"])
    except DemoFileError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as err:
        raise DemoFileError(path, f"unreadable (truncated or corrupt?): {err}") from None
    try:
        meta = json.loads(meta_text)
    except json.JSONDecodeError as err:
        raise DemoFileError(path, f"meta is not valid JSON: {err}") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise DemoFileError(path, f"not a {FORMAT} file (meta format {meta.get('format')!r})")
    if meta.get("version") != VERSION:
        raise DemoFileError(
            path, f"format version {meta.get('version')!r}; this tsrl reads version {VERSION}"
        )
    for key in ("env_id", "obs_spec", "action"):
        if not isinstance(meta.get(key), str):
            raise DemoFileError(path, f"meta has no {key}")
    _check_shapes(path, arrays)
    for name in ARRAYS:
        a = arrays[name]
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            episode = int(np.argwhere(~np.isfinite(a))[0][0])
            raise DemoFileError(path, f"{name} holds NaN or inf (episode {episode})")
    if arrays["actions"].size and np.abs(arrays["actions"]).max() > 1:
        raise DemoFileError(path, "actions outside [-1, 1]")
    demos = Demonstrations(**arrays, meta=meta)
    if expect is not None:
        _check_spec(path, demos.spec, expect)
    return demos


def _check_shapes(path: Path, a: dict[str, np.ndarray]) -> None:
    obs = a["observation"]
    if obs.ndim != 3:
        raise DemoFileError(path, f"observation has shape {obs.shape}; expected (episodes, steps + 1, dim)")
    n, t1 = obs.shape[:2]
    t = t1 - 1
    expected = {
        "achieved_goal": (n, t1, None),
        "desired_goal": (n, t1, None),
        "actions": (n, t, None),
        "rewards": (n, t),
        "is_success": (n, t),
        "seeds": (n,),
    }
    for name, shape in expected.items():
        got = a[name].shape
        if len(got) != len(shape) or any(s is not None and s != g for s, g in zip(shape, got, strict=True)):
            want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
            raise DemoFileError(path, f"{name} has shape {got}; expected {want} (truncated or edited?)")
    if a["achieved_goal"].shape != a["desired_goal"].shape:
        raise DemoFileError(path, "achieved_goal and desired_goal differ in shape")
    if n and t < 1:
        raise DemoFileError(path, "episodes without steps")


def _check_spec(path: Path, got: DemoSpec, expect: DemoSpec) -> None:
    diffs = [
        f"{name} {getattr(got, name)!r} (this run: {getattr(expect, name)!r})"
        for name in ("env_id", "obs_spec", "action", "obs_dim", "goal_dim", "action_dim")
        if getattr(got, name) != getattr(expect, name)
    ]
    if diffs:
        raise DemoFileError(path, "recorded for another environment: " + "; ".join(diffs))


def sha256(path: Path | str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# -- recording -------------------------------------------------------------------------------------
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
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 0:
        raise InvalidConfig(f"episodes must be an integer >= 0; got {episodes!r}")
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


# -- the demonstration buffer ----------------------------------------------------------------------
class DemoReplayBuffer(FeatureHerReplayBuffer):
    """The replay buffer plus a demonstration buffer; `batch_share` of each batch comes from the latter.

    The demonstration buffer is a FeatureHerReplayBuffer of its own (same HER settings), filled once by
    `set_demos`; it pickles with this buffer, so checkpoints and resume keep it. The demonstration
    rows of the latest batch are `last_demo_batch` (for the BC loss). Without demonstrations, or with
    a share that rounds to 0 rows, `sample` is FeatureHerReplayBuffer's, unchanged.

    Args (beyond FeatureHerReplayBuffer's):
        demo_share: fraction of each batch drawn from the demonstrations, in [0, 1).
    """

    def __init__(self, *args: Any, demo_share: float = 0.125, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self.demo_share = demo_share
        self.demo_buffer: FeatureHerReplayBuffer | None = None
        self.last_demo_batch: DictReplayBufferSamples | None = None

    def set_demos(self, demos: Demonstrations) -> None:
        """Fills the demonstration buffer with the episodes of `demos` (replacing any)."""
        self.last_demo_batch = None
        if demos.n_episodes == 0:
            self.demo_buffer = None
            return
        buffer = FeatureHerReplayBuffer(
            demos.n_transitions,
            self.observation_space,
            self.action_space,
            self.env,  # type: ignore[arg-type]
            device=self.device,
            n_sampled_goal=self.n_sampled_goal,
            goal_selection_strategy=self.goal_selection_strategy.name.lower(),
            relabel_features=self.relabel_features,
        )
        t = demos.episode_steps
        for i in range(demos.n_episodes):
            for step in range(t):
                last = step == t - 1
                buffer.add(
                    {key: getattr(demos, key)[i, step][None] for key in OBS_KEYS},
                    {key: getattr(demos, key)[i, step + 1][None] for key in OBS_KEYS},
                    demos.actions[i, step][None],
                    demos.rewards[i, step][None],
                    np.array([last]),
                    [{"TimeLimit.truncated": last}],  # time-limit ends: no terminal bootstrap cut
                )
        self.demo_buffer = buffer

    def demo_rows(self, batch_size: int) -> int:
        """Rows of a batch of `batch_size` drawn from the demonstrations."""
        return 0 if self.demo_buffer is None else round(self.demo_share * batch_size)

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> DictReplayBufferSamples:  # type: ignore[override]
        """(batch_size - n) replay rows, then n demonstration rows (n = demo_rows(batch_size))."""
        n = self.demo_rows(batch_size)
        if n == 0:
            return super().sample(batch_size, env)
        replay = super().sample(batch_size - n, env)
        assert self.demo_buffer is not None
        demo = self.demo_buffer.sample(n, env)
        self.last_demo_batch = demo
        return DictReplayBufferSamples(
            observations={
                k: th.cat((replay.observations[k], demo.observations[k])) for k in replay.observations
            },
            actions=th.cat((replay.actions, demo.actions)),
            next_observations={
                k: th.cat((replay.next_observations[k], demo.next_observations[k]))
                for k in replay.next_observations
            },
            dones=th.cat((replay.dones, demo.dones)),
            rewards=th.cat((replay.rewards, demo.rewards)),
        )

    def set_env(self, env: VecEnv) -> None:
        super().set_env(env)
        if self.demo_buffer is not None:
            self.demo_buffer.set_env(env)

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["last_demo_batch"] = None
        return state


def _first_env(venv: VecEnv) -> gym.Env:
    """The first environment inside a (VecNormalize-wrapped) DummyVecEnv."""
    while hasattr(venv, "venv"):
        venv = venv.venv
    return venv.envs[0]  # type: ignore[attr-defined]


def attach_demos(
    model: OffPolicyAlgorithm, cfg: DemoConfig, normalizer: VecNormalize | None
) -> Demonstrations:
    """Loads `cfg.path` (checked against the model's env), fills the demonstration buffer, lets the
    normaliser see the demonstration states (as OpenAI baselines' DDPG + demonstrations does) and
    attaches the BC loss. For a new model; a resumed one has its buffer and statistics already."""
    assert cfg.path is not None and model.env is not None
    demos = load_demos(cfg.path, DemoSpec.of(_first_env(model.env)))
    buffer = model.replay_buffer
    assert isinstance(buffer, DemoReplayBuffer)
    if cfg.batch_share == 0:  # no demonstration rows: nothing to fill, clone or normalise
        return demos
    buffer.set_demos(demos)
    if normalizer is not None and demos.n_episodes:
        for key in OBS_KEYS:
            if key in normalizer.obs_rms:
                values = getattr(demos, key)
                normalizer.obs_rms[key].update(values.reshape(-1, values.shape[-1]))
    attach_bc_loss(model, cfg)
    return demos


# -- the Q-filtered behaviour-cloning loss ---------------------------------------------------------
def q_filtered_bc_loss(
    actor_actions: th.Tensor, demo_actions: th.Tensor, q_demo: th.Tensor, q_actor: th.Tensor, q_filter: bool
) -> tuple[th.Tensor, th.Tensor]:
    """(L_BC, mask): actions (n, k), Q values (n, 1) -> scalar mean over the n rows of
    mask * ||pi(s) - a||^2, and the (n,) bool mask (Q(s, a_demo) > Q(s, pi(s)), or all True)."""
    if q_filter:
        mask = (q_demo > q_actor).reshape(-1)
    else:
        mask = th.ones(demo_actions.shape[0], dtype=th.bool, device=demo_actions.device)
    squared = ((actor_actions - demo_actions) ** 2).sum(dim=1)
    return (squared * mask).mean(), mask


class BCLoss:
    """Step pre-hook of the actor optimizer: back-propagates weight * L_BC on the last demo rows.

    Records train/bc_loss and train/q_filter_pass (share of demonstration rows cloned) in the model's
    logger (the latest gradient step's values).
    """

    def __init__(self, model: OffPolicyAlgorithm, weight: float, q_filter: bool):
        self.model = model
        self.weight = weight
        self.q_filter = q_filter

    def _actor_action(self, obs: dict[str, th.Tensor]) -> th.Tensor:
        actor = self.model.actor  # type: ignore[attr-defined]
        return actor(obs, deterministic=True) if isinstance(self.model, SAC) else actor(obs)

    def __call__(self, optimizer: th.optim.Optimizer, args: Any, kwargs: Any) -> None:
        buffer = self.model.replay_buffer
        demo = buffer.last_demo_batch if isinstance(buffer, DemoReplayBuffer) else None
        if demo is None:
            return
        critic = self.model.critic  # type: ignore[attr-defined]
        with th.enable_grad():
            pi = self._actor_action(demo.observations)
            with th.no_grad():
                q_demo = critic.q1_forward(demo.observations, demo.actions)
                q_actor = critic.q1_forward(demo.observations, pi)
            loss, mask = q_filtered_bc_loss(pi, demo.actions, q_demo, q_actor, self.q_filter)
            (self.weight * loss).backward()
        self.model.logger.record("train/bc_loss", loss.item())
        self.model.logger.record("train/q_filter_pass", mask.float().mean().item())


def attach_bc_loss(model: OffPolicyAlgorithm, cfg: DemoConfig) -> RemovableHandle | None:
    """Registers BCLoss on the actor's optimizer (after creating or loading a model); None if
    bc_weight is 0."""
    if cfg.bc_weight == 0:
        return None
    optimizer = model.actor.optimizer  # type: ignore[attr-defined]
    return optimizer.register_step_pre_hook(BCLoss(model, cfg.bc_weight, cfg.q_filter))


# -- run folders -----------------------------------------------------------------------------------
def demo_record(cfg: TrainConfig) -> dict[str, Any] | None:
    """What a run folder records about its demonstrations (absolute path, sha256, counts), after
    checking the file against the run's environment; None without demonstrations."""
    if not cfg.agent.demos.enabled:
        return None
    path = Path(cfg.agent.demos.path).resolve()  # type: ignore[arg-type]
    env = gym.make(cfg.gym_id, **cfg.env_kwargs)
    try:
        demos = load_demos(path, DemoSpec.of(env))
    finally:
        env.close()
    return {
        "path": str(path),
        "sha256": sha256(path),
        "episodes": demos.n_episodes,
        "transitions": demos.n_transitions,
        "demonstrator": demos.meta.get("demonstrator"),
    }


def check_demo_record(run_dir: Path | str, cfg: TrainConfig) -> None:
    """Raises DemoFileError if the run's demonstration file no longer has the recorded sha256
    (checked when a run restarts from scratch; a checkpoint holds its own copy of the demonstrations)."""
    record_path = Path(run_dir) / DEMOS_RECORD
    if not cfg.agent.demos.enabled or not record_path.is_file():
        return
    recorded = json.loads(record_path.read_text())
    now = demo_record(cfg)
    assert now is not None
    if now["sha256"] != recorded["sha256"]:
        raise DemoFileError(
            now["path"],
            f"changed since the run started (sha256 {now['sha256'][:12]}, recorded {recorded['sha256'][:12]})",
        )


def summary_line(demos: Demonstrations, path: Path | str) -> str:
    m = demos.meta
    rate = m["kept"] / m["attempted"] if m["attempted"] else math.nan
    return (
        f"wrote {path}: {demos.n_episodes} episodes x {demos.episode_steps} steps of {m['env_id']} "
        f"(obs {m['obs']!r}, action {m['action']}) from {m['demonstrator']}; "
        f"kept {m['kept']} of {m['attempted']} attempted ({rate:.0%})"
    )


__all__: tuple[str, ...] = (
    "BCLoss",
    "DemoFileError",
    "DemoReplayBuffer",
    "DemoSpec",
    "Demonstrations",
    "PolicyDemonstrator",
    "ReachController",
    "ScriptedPickPlace",
    "attach_bc_loss",
    "attach_demos",
    "load_demos",
    "q_filtered_bc_loss",
    "record_demos",
    "save_demos",
)
