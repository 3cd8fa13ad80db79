"""Demonstration files (for learning from demonstrations, tsrl.agents.demos): the data, its .npz
format, writing and checked reading, and what a run folder records about the file it trained with.

`save_demos` / `load_demos` write and read demonstrations as one `.npz` file (format below), checked on
load: a missing, truncated or corrupt file, NaN/inf, or a file from another environment, observation
spec or action mode is one `DemoFileError` that says what differs. `tsrl.agents.demonstrators` records
them. The same demonstrations may be a Minari dataset folder instead (tsrl.agents.demo_minari): a path
ending in .minari is written as one, a folder is read as one, with the same checks; so is a LeRobot
dataset folder (one with meta/info.json, tsrl.agents.demo_lerobot).

## File format (version 1)
One `np.savez_compressed` archive, readable with `np.load(path)` (no pickles). N episodes of T steps:

| array | shape | dtype | meaning |
| --- | --- | --- | --- |
| meta | () | str | JSON: format "tsrl-demos", version, env_id, obs (as given), obs_spec (the env's), action (mode), task_sha256 (of the task file's bytes; absent in older files), task_files (roles -> sha256 of the robot file, robot model and scene it reads; absent in older files), demonstrator, tsrl_version, attempted (episodes run), kept |
| observation | (N, T+1, d) | float64 | `observation` at reset and after each step |
| achieved_goal | (N, T+1, g) | float64 | |
| desired_goal | (N, T+1, g) | float64 | |
| actions | (N, T, k) | float32 | actions executed, in [-1, 1] |
| rewards | (N, T) | float32 | env rewards |
| is_success | (N, T) | bool | `info["is_success"]` after each step |
| seeds | (N,) | int64 | `env.reset(seed=...)` of each episode |

Every episode has the environment's full length (T steps, ended by its time limit); an episode cut
short (a physics blow-up) is dropped while recording. A file whose task_sha256 is not that of the
training task's file (recorded on another task file with the same observation), or whose task_files
(the sha256 of the robot file, robot model and scene the task reads) differ from theirs now, or whose rewards are
not the task's own (recomputed with the env's compute_reward from the stored goals), is refused when
a run starts (demo_record).
"""

from __future__ import annotations

import hashlib
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.keys import OBS_KEYS
from ..exceptions import InvalidConfig, TsrlError
from ..files import replacing
from .config import TrainConfig
from .demo_lerobot import LeRobotDemoError, is_lerobot, read_lerobot
from .demo_minari import SUFFIX as MINARI_SUFFIX
from .demo_minari import MinariDemoError, is_minari, read_minari, write_minari
from .task_record import task_files

FORMAT = "tsrl-demos"
VERSION = 1
#: Arrays of a demonstration file besides `meta`.
ARRAYS: tuple[str, ...] = (
    *OBS_KEYS,
    "actions",
    "rewards",
    "is_success",
    "seeds",
)
#: A run folder's record of the demonstrations it trained with (path, sha256, counts).
DEMOS_RECORD = "demos.json"


class DemoFileError(TsrlError):
    """A demonstration file that is missing, unreadable, inconsistent or for another environment."""

    def __init__(self, path: Path | str, why: str):
        super().__init__(f"demonstration file {path}: {why}")


@dataclass(frozen=True)
class DemoSpec:
    """What a demonstration must match to be used on an environment."""

    env_id: str
    obs_spec: str
    action: str
    obs_dim: int
    goal_dim: int
    action_dim: int
    task_sha256: str | None = None
    """The sha256 of the task file's bytes (None: a task built in code, or a file from before it was kept)."""
    task_files: tuple[tuple[str, str], ...] | None = None
    """(roles, sha256) of every other file the task reads: its robot file, the robot's model, the scene
    (tsrl.agents.task_record.task_files; roles joined by "+"). None: a task built in code, or a file
    from before they were kept."""

    @classmethod
    def of(cls, env: gym.Env) -> DemoSpec:
        """The spec of a tsrl environment (made with gym.make)."""
        base = env.unwrapped
        if not hasattr(base, "obs_spec") or not hasattr(base, "relabel"):
            raise InvalidConfig(f"{env.spec.id if env.spec else env}: demonstrations need a tsrl environment")
        tsrl_env: Any = base  # a TaskEnv (checked above): its action mode
        space = base.observation_space
        assert isinstance(space, gym.spaces.Dict) and base.action_space.shape is not None  # a tsrl env's
        return cls(
            env_id=env.spec.id if env.spec is not None else type(base).__name__,
            obs_spec=base.obs_spec,
            action=tsrl_env.action_mode,
            obs_dim=int(np.prod(space["observation"].shape or ())),
            goal_dim=int(np.prod(space["desired_goal"].shape or ())),
            action_dim=int(base.action_space.shape[0]),
            task_sha256=_task_sha256(tsrl_env.task.source),
            task_files=_task_file_digests(tsrl_env.task.source),
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
            m.get("task_sha256"),
            tuple(m["task_files"].items()) if m.get("task_files") is not None else None,
        )


def save_demos(demos: Demonstrations, path: Path | str) -> Path:
    """Writes `demos` to `path` (.npz, or a Minari dataset folder for a path ending in .minari; written
    whole, then renamed into place). Returns the path."""
    path = Path(path)
    arrays = {name: getattr(demos, name) for name in ARRAYS}
    if path.suffix == MINARI_SUFFIX:
        return write_minari(arrays, demos.meta, path)
    if path.suffix != ".npz":
        raise InvalidConfig(
            f"a demonstration file ends in .npz (or {MINARI_SUFFIX}: a Minari dataset); got {path}"
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, meta=np.array(json.dumps(demos.meta)), **arrays)
    return path


def load_demos(path: Path | str, expect: DemoSpec | None = None) -> Demonstrations:
    """Reads and checks a demonstration file (or a LeRobot or Minari dataset folder); with `expect`, it
    must match that environment spec.

    Raises DemoFileError (missing, truncated or corrupt, another format, inconsistent shapes, NaN/inf,
    actions outside [-1, 1], or a spec that differs from `expect`, naming the differences; for a Minari
    dataset also episodes that do not end by their time limit, demo_minari.read_minari).
    """
    path = Path(path)
    if is_lerobot(path):  # a folder with meta/info.json (tsrl.agents.demo_lerobot)
        try:
            arrays, meta = read_lerobot(path)
        except LeRobotDemoError as err:
            raise DemoFileError(path, str(err)) from None
        return _checked(path, arrays, meta, expect)
    if is_minari(path):
        try:
            arrays, meta = read_minari(path, {"format": FORMAT, "version": VERSION})
        except MinariDemoError as err:
            raise DemoFileError(path, str(err)) from None
        return _checked(path, arrays, meta, expect)
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
    return _checked(path, arrays, meta, expect)


def _checked(path: Path, arrays: dict[str, np.ndarray], meta: Any, expect: DemoSpec | None) -> Demonstrations:
    """The demonstrations of `arrays` and `meta` read from `path`, after the checks of load_demos."""
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
    if (
        got.task_sha256 is not None
        and expect.task_sha256 is not None
        and got.task_sha256 != expect.task_sha256
    ):
        diffs.append(
            f"task file sha256 {got.task_sha256[:12]} (this run's task file: {expect.task_sha256[:12]}; "
            "recorded on another task file)"
        )
    if got.task_files is not None and expect.task_files is not None:
        now = dict(expect.task_files)
        diffs += [
            f"{roles} file sha256 {digest[:12]} (this run's: {now[roles][:12]}; changed since the recording)"
            for roles, digest in got.task_files
            if roles in now and now[roles] != digest
        ]
    if diffs:
        raise DemoFileError(path, "recorded for another environment: " + "; ".join(diffs))


def _task_sha256(source: Path | None) -> str | None:
    """The sha256 of a task file's bytes; None for a task built in code."""
    return None if source is None else sha256(source)


def _task_file_digests(source: Path | None) -> tuple[tuple[str, str], ...] | None:
    """DemoSpec.task_files of the task file `source`; None for a task built in code."""
    if source is None:
        return None
    return tuple(("+".join(f.roles), sha256(f.path)) for f in task_files(source) if "task" not in f.roles)


def step_goals(demos: Demonstrations) -> tuple[np.ndarray, np.ndarray]:
    """(achieved, desired) goals after each step, (N * T, g) each: what each stored reward reads."""
    g = demos.achieved_goal.shape[2]
    return demos.achieved_goal[:, 1:].reshape(-1, g), demos.desired_goal[:, 1:].reshape(-1, g)


def check_rewards(path: Path | str, demos: Demonstrations, env: gym.Env) -> None:
    """Raises DemoFileError unless the stored rewards are the task's: `env`'s goal's task_reward of each
    step's achieved and desired goals (after the step; the reward at the tolerances, whatever the
    env's reward scale), to float32 rounding."""
    if not demos.n_transitions:
        return
    base: Any = env.unwrapped  # a tsrl TaskEnv (DemoSpec.of checked it)
    expected = np.asarray(base.goal.task_reward(*step_goals(demos)), dtype=np.float32)
    stored = demos.rewards.reshape(-1).astype(np.float32)
    wrong = ~np.isclose(stored, expected, rtol=1e-5, atol=1e-5)
    if wrong.any():
        first = int(np.argmax(wrong))
        episode, step = divmod(first, demos.episode_steps)
        raise DemoFileError(
            path,
            f"rewards are not the task's: {int(wrong.sum())} of {wrong.size} differ from compute_reward of "
            f"the stored goals (first: episode {episode} step {step}, stored {stored[first]:g}, "
            f"the task's {expected[first]:g})",
        )


def sha256(path: Path | str) -> str:
    """The SHA-256 of a file, or of a folder (a Minari dataset): its files' relative paths and bytes."""
    h = hashlib.sha256()
    path = Path(path)
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    for file in files:
        if file != path:
            h.update(file.relative_to(path).as_posix().encode() + b"\0")
        with open(file, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    return h.hexdigest()


def demo_record(cfg: TrainConfig) -> dict[str, Any] | None:
    """What a run folder records about its demonstrations (absolute path, sha256, counts), after
    checking the file against the run's environment; None without demonstrations."""
    if not cfg.agent.demos.active:
        return None
    path = Path(cfg.agent.demos.path).resolve()  # type: ignore[arg-type]
    env = gym.make(cfg.gym_id, **cfg.env_kwargs)
    try:
        demos = load_demos(path, DemoSpec.of(env))
        check_rewards(path, demos, env)
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
    if not cfg.agent.demos.active or not record_path.is_file():
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
