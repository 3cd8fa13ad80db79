"""Demonstrations as Minari datasets (Farama's offline-RL format for Gymnasium environments): the arrays
and meta of a demonstration file (tsrl.agents.demo_files), written as a Minari dataset folder and read
back from one, with the checks only a Minari dataset needs (the episode ends); `demo_files` does the
others (meta, shapes, NaN/inf, the environment) on what `read_minari` returns, as for a .npz file.

## The folder
`write_minari(arrays, meta, "reach.minari")` writes a Minari datasets root (what MINARI_DATASETS_PATH
names) holding one dataset, `tsrl/<task>/<name>-v0` (`tsrl/UR5eReach/reach-v0` for reach.minari): with
`MINARI_DATASETS_PATH=reach.minari`, `minari.load_dataset("tsrl/UR5eReach/reach-v0")` and `minari list
local` find it. `read_minari` takes that root (if it holds one dataset), a dataset's folder
(`~/.minari/datasets/tsrl/UR5eReach/reach-v0`) or its `data/` folder.

## Each episode (Minari's EpisodeData), N episodes of T steps
| field | shape | meaning |
| --- | --- | --- |
| observations | dict of (T+1, d) | `observation`, `achieved_goal`, `desired_goal` at reset and after each step |
| actions | (T, k) float32 | actions executed, in [-1, 1] |
| rewards | (T,) float32 | env rewards |
| terminations | (T,) bool | all False (a demonstration never terminates) |
| truncations | (T,) bool | True at the last step only (every episode ends by its time limit) |
| infos["is_success"] | (T,) bool | `info["is_success"]` after each step; (T+1,) as Minari's DataCollector records it, the reset's first, is read too |
| seed (episode metadata) | int | `env.reset(seed=...)` of the episode |

The dataset's metadata holds the file's meta under `tsrl` (env id, observation spec, action mode,
demonstrator, episodes attempted and kept) and, for a registered environment, its Gymnasium EnvSpec
(`dataset.recover_environment()` remakes it once tsrl is installed). A dataset written by
Minari's own tools on a tsrl environment (`create_dataset_from_buffers`; the DataCollector with
`record_infos=True` builds the same episodes) has no `tsrl` entry: its meta is read off the
environment its EnvSpec makes.
"""

from __future__ import annotations

import contextlib
import os
import re
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from ..envs.keys import OBS_KEYS
from ..exceptions import InvalidConfig, TsrlError
from ..files import replacing

SUFFIX = ".minari"
#: The key of the dataset's metadata that holds the demonstration file's meta.
META_KEY = "tsrl"
_INSTALL = "Minari datasets need the minari package: pip install 'tsrl[minari]'"


class MinariDemoError(TsrlError):
    """A Minari dataset that is not usable as demonstrations (the message says why, without the path)."""


def minari_path(out: Path | str) -> Path:
    """The Minari dataset folder written beside the .npz file `out`: `out` with the suffix .minari."""
    return Path(out).with_suffix(SUFFIX)


def is_minari(path: Path | str) -> bool:
    """Whether `path` is read as a Minari dataset (a folder) rather than a .npz file."""
    return Path(path).is_dir()


def dataset_id(meta: Mapping[str, Any], path: Path) -> str:
    """The Minari id of the dataset written to `path`: tsrl/<task>/<folder name>-v0 (characters Minari's
    ids do not allow become -)."""
    task = re.sub(r"-v\d+$", "", str(meta["env_id"]).rpartition("/")[2])
    return "/".join(re.sub(r"[^\w-]", "-", part) for part in ("tsrl", task, path.stem)) + "-v0"


def write_minari(arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any], path: Path | str) -> Path:
    """Writes demonstrations (the arrays of demo_files.ARRAYS and their meta) as the Minari dataset
    folder `path` (ending in .minari; written whole, then renamed into place; a tsrl dataset already
    there is replaced, anything else is refused). Returns the path."""
    minari = import_minari()
    path = Path(path)
    if path.suffix != SUFFIX:
        raise InvalidConfig(f"a Minari dataset folder ends in {SUFFIX}; got {path}")
    if path.exists() and not _written_by_tsrl(path):
        raise InvalidConfig(f"{path} exists and is not a tsrl Minari dataset; remove it or write elsewhere")
    env = _recording_env(meta)
    n, t = arrays["actions"].shape[:2]
    buffers = [
        minari.data_collector.EpisodeBuffer(
            seed=int(arrays["seeds"][i]),
            observations={key: arrays[key][i] for key in OBS_KEYS},
            actions=arrays["actions"][i],
            rewards=arrays["rewards"][i],
            terminations=np.zeros(t, dtype=bool),
            truncations=np.arange(t) == t - 1,
            infos={"is_success": arrays["is_success"][i]},
        )
        for i in range(n)
    ]
    path.parent.mkdir(parents=True, exist_ok=True)
    with (
        contextlib.closing(env) if env is not None else contextlib.nullcontext(),
        replacing(path) as root,
        _datasets_root(root),
        warnings.catch_warnings(),
    ):
        # Minari warns about each optional field left empty (author, e-mail, code permalink, ...).
        warnings.filterwarnings("ignore", category=UserWarning, module=r"minari\.")
        dataset = minari.create_dataset_from_buffers(
            dataset_id(meta, path),
            buffers,
            env=env,
            observation_space=None if env is not None else _observation_space(arrays),
            action_space=None if env is not None else gym.spaces.Box(-1, 1, arrays["actions"].shape[2:]),
            algorithm_name=str(meta["demonstrator"]),
            description=f"tsrl demonstrations of {meta['env_id']} (obs {meta['obs']!r}, action {meta['action']})",
            requirements=["tsrl"],
        )
        dataset.storage.update_metadata({META_KEY: dict(meta)})
    return path


def read_minari(
    path: Path | str, file_format: Mapping[str, Any]
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays (demo_files.ARRAYS) and meta of the Minari dataset at `path` (see the module docstring
    for which folders), its episodes stacked; a dataset recorded without tsrl gets `file_format` (the
    meta's format and version) and the rest of its meta from its environment. Raises MinariDemoError
    where the dataset is unreadable or its episodes are not demonstrations: another length, a
    termination, an end that is not a truncation, no seed or no is_success."""
    minari = import_minari()
    data = _data_folder(Path(path))
    try:
        dataset = minari.MinariDataset(data)
        metadata = dataset.storage.metadata
        episodes = list(dataset.iterate_episodes())
        seeds = [m.get("seed") for m in dataset.storage.get_episode_metadata(range(len(episodes)))]
    except (OSError, ValueError, KeyError, TypeError, AssertionError) as err:
        raise MinariDemoError(f"unreadable Minari dataset {data}: {err!r}") from None
    if META_KEY in metadata:
        meta = metadata[META_KEY]
        _check_env_spec(dataset.env_spec, meta)
    else:
        meta = {
            **file_format,
            **_meta_from_env(dataset.env_spec, len(episodes)),
            "demonstrator": f"minari:{dataset.id}",
        }
    space = metadata["observation_space"]
    if not isinstance(space, gym.spaces.Dict) or not set(OBS_KEYS) <= set(space.spaces):
        raise MinariDemoError(f"observations are not a dict of {', '.join(OBS_KEYS)}; got {space}")
    if not episodes:
        steps = dataset.env_spec.max_episode_steps if dataset.env_spec is not None else 0
        return _empty(space, dataset.action_space, steps or 0), meta
    t = len(episodes[0])
    columns: dict[str, list[np.ndarray]] = {
        name: [] for name in (*OBS_KEYS, "actions", "rewards", "is_success")
    }
    for i, (episode, seed) in enumerate(zip(episodes, seeds, strict=True)):
        _check_episode(i, episode, seed, t)
        for key in OBS_KEYS:
            columns[key].append(np.asarray(episode.observations[key], dtype=np.float64))
        columns["actions"].append(np.asarray(episode.actions, dtype=np.float32))
        columns["rewards"].append(np.asarray(episode.rewards, dtype=np.float32))
        success = np.asarray(episode.infos["is_success"], dtype=bool)  # _check_episode: present
        columns["is_success"].append(success[-t:])  # DataCollector's first is the reset's
    arrays = {name: _stack(name, values) for name, values in columns.items()}
    arrays["seeds"] = np.asarray(seeds, dtype=np.int64)
    return arrays, meta


def _check_episode(i: int, episode: Any, seed: Any, t: int) -> None:
    steps = len(episode)
    if steps != t:
        raise MinariDemoError(
            f"episode {i} has {steps} steps, episode 0 {t}: demonstrations run to their time limit"
        )
    terminations = np.asarray(episode.terminations, dtype=bool)
    truncations = np.asarray(episode.truncations, dtype=bool)
    if terminations.any():
        raise MinariDemoError(f"episode {i} terminates at step {int(np.argmax(terminations))}")
    if not truncations[-1:].all():
        raise MinariDemoError(
            f"episode {i} does not end by its time limit (truncations[{steps - 1}] is False): cut short?"
        )
    if truncations[:-1].any():
        raise MinariDemoError(
            f"episode {i} is truncated at step {int(np.argmax(truncations))}, before its end"
        )
    success = (episode.infos or {}).get("is_success")
    if success is None or np.shape(success) not in ((t,), (t + 1,)):
        got = "none" if success is None else f"shape {np.shape(success)}"
        raise MinariDemoError(f"episode {i}'s infos['is_success'] has {got}; expected ({t},) or ({t + 1},)")
    if seed is None:
        raise MinariDemoError(f"episode {i} has no seed (its reset's seed, to replay it)")


def _stack(name: str, values: list[np.ndarray]) -> np.ndarray:
    for i, v in enumerate(values):
        if v.shape != values[0].shape:
            raise MinariDemoError(f"episode {i}'s {name} has shape {v.shape}, episode 0's {values[0].shape}")
    return np.stack(values)


def _data_folder(path: Path) -> Path:
    """The `data/` folder of the one dataset at `path` (a datasets root, a dataset's folder or its data/)."""
    if (path / "metadata.json").is_file():
        return path
    found = sorted(p.parent for p in path.rglob("metadata.json") if p.parent.name == "data")
    if len(found) != 1:
        what = "no Minari dataset (no data/metadata.json)" if not found else f"{len(found)} Minari datasets"
        raise MinariDemoError(f"holds {what}; give one dataset's folder")
    return found[0]


def _written_by_tsrl(path: Path) -> bool:
    try:
        metadata = import_minari().MinariDataset(_data_folder(path)).storage.metadata
    except (MinariDemoError, OSError, ValueError, KeyError):
        return False
    return META_KEY in metadata


def _check_env_spec(env_spec: gym.envs.registration.EnvSpec | None, meta: Any) -> None:
    """Raises MinariDemoError where the dataset's EnvSpec (id, obs, action) contradicts its tsrl meta."""
    if env_spec is None or not isinstance(meta, dict):
        return
    told = {"env_id": env_spec.id} | {
        key: env_spec.kwargs[key] for key in ("obs", "action") if key in env_spec.kwargs
    }
    for key, value in told.items():
        if key in meta and meta[key] != value:
            raise MinariDemoError(
                f"its env_spec has {key} {value!r} but its tsrl metadata {meta[key]!r}: it contradicts "
                "itself (edited?); record it again"
            )


def _meta_from_env(env_spec: gym.envs.registration.EnvSpec | None, n: int) -> dict[str, Any]:
    """The demonstration meta of a dataset recorded without tsrl: read off the env its EnvSpec makes."""
    if env_spec is None:
        raise MinariDemoError(
            f"has neither tsrl's metadata ({META_KEY!r}) nor an env_spec to tell its environment"
        )
    try:
        env = gym.make(env_spec)
    except Exception as err:  # noqa: BLE001 - any failure to make the recorded env is this one error
        raise MinariDemoError(f"its env_spec {env_spec.id!r} does not make an environment: {err}") from None
    base = env.unwrapped
    env.close()
    if not hasattr(base, "obs_spec") or not hasattr(base, "action_mode"):
        raise MinariDemoError(f"recorded on {env_spec.id!r}, not a tsrl environment")
    return {
        "env_id": env_spec.id,
        "obs": env_spec.kwargs.get("obs", base.obs_spec),
        "obs_spec": base.obs_spec,
        "action": base.action_mode,
        "attempted": n,
        "kept": n,
    }


def _recording_env(meta: Mapping[str, Any]) -> gym.Env | None:
    """The registered environment the demonstrations were recorded on (its EnvSpec goes into the
    dataset); None for a task file (tsrl/Task-v0: the file's path is not in the meta)."""
    from ..envs import TASK_ENV_ID

    if meta["env_id"] == TASK_ENV_ID:
        return None
    env = gym.make(meta["env_id"], obs=meta["obs"])
    if getattr(env.unwrapped, "action_mode", None) != meta["action"]:  # recorded in a built-in mode
        env.close()
        env = gym.make(meta["env_id"], obs=meta["obs"], action=meta["action"])
    return env


def _observation_space(arrays: Mapping[str, np.ndarray]) -> gym.spaces.Dict:
    """A TaskEnv's observation space (unbounded float64 vectors) of the arrays' sizes."""
    return gym.spaces.Dict(
        {key: gym.spaces.Box(-np.inf, np.inf, arrays[key].shape[2:], dtype=np.float64) for key in OBS_KEYS}
    )


def _empty(space: gym.spaces.Dict, action_space: gym.Space, t: int) -> dict[str, np.ndarray]:
    """The arrays of a dataset without episodes (T from its EnvSpec's time limit, else 0)."""
    return {
        **{key: np.zeros((0, t + 1, *(space[key].shape or ()))) for key in OBS_KEYS},
        "actions": np.zeros((0, t, *(action_space.shape or ())), dtype=np.float32),
        "rewards": np.zeros((0, t), dtype=np.float32),
        "is_success": np.zeros((0, t), dtype=bool),
        "seeds": np.zeros(0, dtype=np.int64),
    }


@contextlib.contextmanager
def _datasets_root(root: Path) -> Iterator[None]:
    """MINARI_DATASETS_PATH = `root` within the block (Minari writes under that root), then as it was."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root.absolute())  # Minari sizes a relative root wrongly
    try:
        yield
    finally:
        if before is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = before


def import_minari() -> Any:
    try:
        import minari
        import minari.data_collector
    except ImportError:
        raise InvalidConfig(_INSTALL) from None
    return minari
