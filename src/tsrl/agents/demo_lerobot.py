"""Demonstrations and rollouts as LeRobotDataset v3 folders (Hugging Face LeRobot's format), written and
read with pyarrow and JSON alone (no `lerobot` package): the arrays and meta of a demonstration file
(tsrl.agents.demo_files) as a dataset folder, and back, with the checks only such a dataset needs (its
version, its writer, its frames); `demo_files` does the others (meta, shapes, NaN/inf, the environment)
on what `read_lerobot` returns, as for a .npz file.

## The folder (one chunk, one file each)
```
DIR/meta/info.json                          codebase_version "v3.0", fps, robot_type, features, splits,
                                            path templates; "tsrl": the demonstration meta, the task
                                            file's text and sha256, the observation's layout
DIR/meta/stats.json                         min, max, mean, std, count of every numeric feature
DIR/meta/tasks.parquet                      the task's language string (index) -> task_index 0
DIR/meta/episodes/chunk-000/file-000.parquet  one row per episode: length, tasks, where its frames are
                                            (dataset_from_index, dataset_to_index, data/chunk_index,
                                            data/file_index), seed, final.observation.*
DIR/data/chunk-000/file-000.parquet         one row per frame (below)
```

## Each frame (one env step t of episode e; N episodes of T steps give N T frames)
| column | shape | dtype | meaning |
| --- | --- | --- | --- |
| observation.state | (d,) | float64 | `observation` before the step |
| observation.achieved_goal, observation.desired_goal | (g,) | float64 | the goals before the step |
| observation.<feature> | (rows,) | float64 | each task map of `observation` (env.observation_structure), its unit in the feature's `unit` |
| action | (k,) | float32 | action executed, in [-1, 1] |
| next.reward | () | float32 | env reward of the step |
| next.done, next.truncated | () | bool | True at the last step only (every episode ends by its time limit) |
| next.success | () | bool | `info["is_success"]` after the step |
| episode_index, frame_index (t), index (e T + t), task_index (0) | () | int64 | |
| timestamp | () | float32 | t x the task's control period [s] (fps = 1 / control period) |

The observation after the last step (LeRobot datasets have no frame for it) is the episode's
`final.observation.state`, `final.observation.achieved_goal` and `final.observation.desired_goal`.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from ..envs.keys import OBS_KEYS
from ..envs.observations import PREVIOUS_ACTIONS
from ..exceptions import InvalidConfig, TsrlError
from ..files import replacing
from .config import TrainConfig
from .lerobot_video import VIDEO_PATH, video_key, write_camera_video

CODEBASE_VERSION = "v3.0"
#: The key of meta/info.json that holds what tsrl needs besides LeRobot's fields.
META_KEY = "tsrl"
INFO = "meta/info.json"
STATS = "meta/stats.json"
TASKS = "meta/tasks.parquet"
EPISODES = "meta/episodes/chunk-000/file-000.parquet"
DATA = "data/chunk-000/file-000.parquet"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
#: The demonstration arrays of the observation -> their data columns.
_STATE = {key: "observation.state" if key == "observation" else f"observation.{key}" for key in OBS_KEYS}
_FINAL = "final."
#: Units of the task maps' values by RAI symbol (velocity(x): x's per second); a map not listed has none.
_UNITS: dict[str, str] = {
    "position": "m",
    "positionDiff": "m",
    "positionRel": "m",
    "distance": "m",
    "quaternion": "1",
    "quaternionDiff": "1",
    "vector": "1",
    "scalarProduct": "1",
    "jointState": "rad (hinge) or m (slide)",
    "jointLimits": "rad (hinge) or m (slide)",
    PREVIOUS_ACTIONS: "1 (action units)",
}
_INSTALL = "LeRobot datasets need the pyarrow package: pip install 'tsrl[lerobot]'"


class LeRobotDemoError(TsrlError):
    """A LeRobot dataset that is not usable as demonstrations (the message says why, without the path)."""


def is_lerobot(path: Path | str) -> bool:
    """Whether `path` is a LeRobot dataset folder (it has meta/info.json)."""
    return (Path(path) / INFO).is_file()


def unit(feature: str) -> str | None:
    """The unit of an observation feature (a task-map spec or previous_actions); None where unknown."""
    inner = re.fullmatch(r"velocity\((.*)\)", feature)
    if inner is not None:
        base = unit(inner.group(1))
        if base is None:
            return None
        return f"{base}/s" if re.fullmatch(r"\w+", base) else f"({base})/s"
    symbol = re.sub(r"[XYZ]*$", "", feature.partition("(")[0])  # vectorZ, scalarProductXZ
    return _UNITS.get(symbol)


class DemoArrays(Protocol):
    """What the writer reads of demonstrations: tsrl.agents.demo_files.Demonstrations (shapes there)."""

    @property
    def observation(self) -> np.ndarray: ...
    @property
    def achieved_goal(self) -> np.ndarray: ...
    @property
    def desired_goal(self) -> np.ndarray: ...
    @property
    def actions(self) -> np.ndarray: ...
    @property
    def rewards(self) -> np.ndarray: ...
    @property
    def is_success(self) -> np.ndarray: ...
    @property
    def seeds(self) -> np.ndarray: ...
    @property
    def meta(self) -> dict[str, Any]: ...


def save_lerobot(
    demos: DemoArrays, path: Path | str, recorded_with: TrainConfig, camera: str | None = None
) -> Path:
    """Writes demonstrations as the LeRobot dataset folder `path`, on the environment `recorded_with`
    makes (it must be the one they were recorded on: its layout and task file go into the metadata);
    with `camera`, also that camera's frames as video (tsrl.agents.lerobot_video, the episodes replayed).
    Written whole, then renamed into place; a tsrl dataset already there is replaced, any other
    existing path is refused. Returns the path."""
    pa, pq = import_pyarrow()
    path = Path(path)
    if path.exists() and not _written_by_tsrl(path):
        raise InvalidConfig(f"{path} exists and is not a tsrl LeRobot dataset; remove it or write elsewhere")
    meta = demos.meta
    arrays = {
        **{key: getattr(demos, key) for key in OBS_KEYS},
        "actions": demos.actions,
        "rewards": demos.rewards,
        "is_success": demos.is_success,
        "seeds": demos.seeds,
    }
    env = gym.make(recorded_with.gym_id, **recorded_with.env_kwargs)
    try:
        layout = _layout(env, arrays, meta)
    finally:
        env.close()
    n, t = arrays["actions"].shape[:2]
    dt = layout["control_dt"]
    frames = _frames(arrays, layout["observation_structure"], dt)
    columns = {name: _arrow(pa, values) for name, values in frames.items()}
    episodes = {
        "episode_index": np.arange(n, dtype=np.int64),
        "length": np.full(n, t, dtype=np.int64),
        "data/chunk_index": np.zeros(n, dtype=np.int64),
        "data/file_index": np.zeros(n, dtype=np.int64),
        "dataset_from_index": np.arange(n, dtype=np.int64) * t,
        "dataset_to_index": (np.arange(n, dtype=np.int64) + 1) * t,
        "meta/episodes/chunk_index": np.zeros(n, dtype=np.int64),
        "meta/episodes/file_index": np.zeros(n, dtype=np.int64),
        "seed": np.asarray(arrays["seeds"], dtype=np.int64),
        **{_FINAL + column: arrays[key][:, -1] for key, column in _STATE.items()},
    }
    episode_columns = {name: _arrow(pa, values) for name, values in episodes.items()}
    episode_columns["tasks"] = pa.array([[layout["task"]]] * n, type=pa.list_(pa.string()))
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": layout["robot"],
        "total_episodes": n,
        "total_frames": n * t,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": _fps(dt),
        "splits": {"train": f"0:{n}"},
        "data_path": DATA_PATH,
        "video_path": None,
        "features": _features(frames, layout),
        META_KEY: {"demos": dict(meta), "episode_steps": t, **layout},
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    with replacing(path) as root:
        if camera is not None:
            feature, video_columns = write_camera_video(root, arrays, recorded_with, camera, info["fps"])
            info["features"][video_key(camera)] = feature
            info["video_path"] = VIDEO_PATH
            episode_columns |= {name: _arrow(pa, values) for name, values in video_columns.items()}
        for name in (DATA, EPISODES, INFO):
            (root / name).parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(columns), root / DATA)
        pq.write_table(pa.table(episode_columns), root / EPISODES)
        import pandas as pd  # type: ignore[import-untyped]  # a tsrl dependency; LeRobot: the task is the index

        tasks = pd.DataFrame({"task_index": [0]}, index=pd.Index([layout["task"]], name="task"))
        pq.write_table(pa.Table.from_pandas(tasks), root / TASKS)
        (root / STATS).write_text(json.dumps(_stats(frames), indent=2) + "\n")
        (root / INFO).write_text(json.dumps(info, indent=2) + "\n")
    return path


def read_lerobot(path: Path | str) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The arrays (demo_files.ARRAYS) and meta of the tsrl LeRobot dataset at `path`. Raises
    LeRobotDemoError where it is another version, was not written by tsrl (another robot's or task's
    dataset), lacks a column, or its frames are not whole demonstration episodes: another length, an end
    before the last frame, an end that is not a truncation, frames out of order."""
    _, pq = import_pyarrow()
    path = Path(path)
    info = _read_info(path)
    tsrl = info.get(META_KEY)
    if not isinstance(tsrl, dict) or not isinstance(tsrl.get("demos"), dict):
        raise LeRobotDemoError(
            f"a LeRobot dataset of robot_type {info.get('robot_type')!r} not written by tsrl (no "
            f"{META_KEY!r} entry in {INFO}); tsrl reads the datasets it writes"
        )
    meta: dict[str, Any] = tsrl["demos"]
    t = tsrl.get("episode_steps")
    if not isinstance(t, int) or t < 1:
        raise LeRobotDemoError(f"{INFO}'s {META_KEY}.episode_steps is {t!r}; expected an integer >= 1")
    try:
        data_files = sorted(path.glob("data/chunk-*/file-*.parquet"))
        episode_files = sorted(path.glob("meta/episodes/chunk-*/file-*.parquet"))
        if not data_files or not episode_files:
            raise LeRobotDemoError(f"no {DATA if not data_files else EPISODES}")
        frames = _concat([pq.read_table(f) for f in data_files])
        episodes = _concat([pq.read_table(f) for f in episode_files])
    except (OSError, ValueError) as err:  # pyarrow's ArrowInvalid is a ValueError
        raise LeRobotDemoError(f"unreadable parquet file: {err}") from None
    n = episodes.num_rows
    step_columns = ("action", "next.reward", "next.done", "next.truncated", "next.success")
    f = {
        name: _column(frames, name)
        for name in (*_STATE.values(), *step_columns, "episode_index", "frame_index")
    }
    e = {
        name: _column(episodes, name)
        for name in ("episode_index", "seed", *(_FINAL + c for c in _STATE.values()))
    }
    if frames.num_rows != n * t:
        raise LeRobotDemoError(f"{frames.num_rows} frames; {n} episodes of {t} steps are {n * t}")
    order = np.lexsort((f["frame_index"], f["episode_index"]))
    f = {name: values[order] for name, values in f.items()}
    if not np.array_equal(np.sort(e["episode_index"]), np.arange(n)):
        raise LeRobotDemoError(f"the episodes' episode_index are not 0..{n - 1}")
    for i in range(n):
        _check_episode(i, {name: values[i * t : (i + 1) * t] for name, values in f.items()}, t)
    by_index = np.argsort(e["episode_index"])

    def episode_major(values: np.ndarray) -> np.ndarray:
        return values.reshape(n, t, *values.shape[1:])

    arrays = {
        key: np.concatenate(
            [episode_major(f[column]), e[_FINAL + column][by_index][:, None]], axis=1, dtype=np.float64
        )
        if n
        else np.zeros((0, t + 1, *f[column].shape[1:]))
        for key, column in _STATE.items()
    }
    arrays["actions"] = episode_major(f["action"]).astype(np.float32)
    arrays["rewards"] = episode_major(f["next.reward"]).astype(np.float32)
    arrays["is_success"] = episode_major(f["next.success"]).astype(bool)
    arrays["seeds"] = e["seed"][by_index].astype(np.int64)
    return arrays, meta


def _check_episode(i: int, f: Mapping[str, np.ndarray], t: int) -> None:
    if not (f["episode_index"] == i).all():
        raise LeRobotDemoError(f"episode {i} has {int((f['episode_index'] == i).sum())} frames, expected {t}")
    if not np.array_equal(f["frame_index"], np.arange(t)):
        raise LeRobotDemoError(f"episode {i}'s frame_index are not 0..{t - 1}")
    done, truncated = f["next.done"].astype(bool), f["next.truncated"].astype(bool)
    if done[:-1].any():
        raise LeRobotDemoError(
            f"episode {i} ends at frame {int(np.argmax(done))} (next.done), before its end"
        )
    if not (done[-1] and truncated[-1]):
        raise LeRobotDemoError(
            f"episode {i} does not end by its time limit (next.done {bool(done[-1])}, next.truncated "
            f"{bool(truncated[-1])} at frame {t - 1}): cut short?"
        )


def _read_info(path: Path) -> dict[str, Any]:
    file = path / INFO
    if not file.is_file():
        raise LeRobotDemoError(f"no {INFO}: not a LeRobot dataset")
    try:
        info = json.loads(file.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise LeRobotDemoError(f"{INFO} is not valid JSON: {err}") from None
    if not isinstance(info, dict):
        raise LeRobotDemoError(f"{INFO} is not a JSON object")
    if info.get("codebase_version") != CODEBASE_VERSION:
        raise LeRobotDemoError(
            f"LeRobot dataset version {info.get('codebase_version')!r}; tsrl reads {CODEBASE_VERSION!r}"
        )
    return info


def _column(table: Any, name: str) -> np.ndarray:
    """Column `name` as an array: (rows,) for scalars, (rows, width) for fixed or equal-length lists."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if name not in table.column_names:
        raise LeRobotDemoError(f"no column {name!r} (columns: {', '.join(table.column_names)})")
    column = table.column(name).combine_chunks()
    if column.null_count:
        raise LeRobotDemoError(f"column {name!r} has {column.null_count} empty values")
    if not (pa.types.is_list(column.type) or pa.types.is_fixed_size_list(column.type)):
        return np.asarray(column.to_numpy(zero_copy_only=False))
    lengths = np.asarray(pc.list_value_length(column).to_numpy(zero_copy_only=False))
    width = int(lengths[0]) if len(lengths) else getattr(column.type, "list_size", 0)
    if (lengths != width).any():
        raise LeRobotDemoError(f"column {name!r} has rows of lengths {sorted(set(lengths.tolist()))}")
    return np.asarray(column.flatten().to_numpy(zero_copy_only=False)).reshape(len(column), width)


def _concat(tables: list[Any]) -> Any:
    import pyarrow as pa

    return pa.concat_tables(tables) if len(tables) > 1 else tables[0]


def _layout(env: gym.Env, arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> dict[str, Any]:
    """What the dataset records of the environment: robot, task string and file, control period, the
    observation's and goals' rows; refused unless the demonstrations' shapes and meta are its own."""
    base: Any = env.unwrapped  # a TaskEnv: recorded_with is a tsrl environment's config
    space = base.observation_space
    got = tuple(meta[k] for k in ("env_id", "obs_spec", "action")) + tuple(
        arrays[k].shape[2:] for k in ("observation", "desired_goal", "actions")
    )
    want = (env.spec.id if env.spec is not None else None, base.obs_spec, base.action_mode) + tuple(
        s.shape for s in (space["observation"], space["desired_goal"], base.action_space)
    )
    if got != want:
        raise InvalidConfig(f"demonstrations of {got} written on another environment {want}")
    task = base.task
    source = Path(task.source) if task.source is not None else None
    text = source.read_text(encoding="utf-8") if source is not None and source.is_file() else None
    return {
        "robot": base.robot.name,
        "task": task.description or task.name,
        "task_name": task.name,
        "task_file": str(source) if source is not None else None,
        "task_file_text": text,
        "task_file_sha256": hashlib.sha256(text.encode()).hexdigest() if text is not None else None,
        "control_dt": float(task.control_dt),
        "observation_structure": {k: [s.start, s.stop] for k, s in base.observation_structure.items()},
        "goal_structure": {k: [s.start, s.stop] for k, s in base.goal_structure.items()},
    }


def _frames(
    arrays: Mapping[str, np.ndarray], structure: Mapping[str, list[int]], dt: float
) -> dict[str, np.ndarray]:
    """The data table's columns, one row per step (episode-major)."""
    n, t = arrays["actions"].shape[:2]
    rows = n * t
    flat = {key: arrays[key][:, :-1].reshape(rows, arrays[key].shape[2]) for key in _STATE}
    frame_index = np.tile(np.arange(t, dtype=np.int64), n)
    last = frame_index == t - 1
    return {
        **{column: flat[key] for key, column in _STATE.items()},
        **{f"observation.{name}": flat["observation"][:, a:b] for name, (a, b) in structure.items()},
        "action": arrays["actions"].reshape(rows, arrays["actions"].shape[2]).astype(np.float32),
        "next.reward": arrays["rewards"].reshape(rows).astype(np.float32),
        "next.done": last,
        "next.truncated": last,
        "next.success": arrays["is_success"].reshape(rows).astype(bool),
        "episode_index": np.repeat(np.arange(n, dtype=np.int64), t),
        "frame_index": frame_index,
        "index": np.arange(rows, dtype=np.int64),
        "task_index": np.zeros(rows, dtype=np.int64),
        "timestamp": (frame_index * dt).astype(np.float32),
    }


def _features(frames: Mapping[str, np.ndarray], layout: Mapping[str, Any]) -> dict[str, Any]:
    """info.json's features: dtype, shape and row names of each column; units of the task maps'."""

    def rows(structure: Mapping[str, list[int]]) -> list[str]:
        names: list[str] = []
        for name, (a, b) in structure.items():
            names += [f"{name}[{i}]" for i in range(b - a)]
        return names

    names = {
        "observation.state": rows(layout["observation_structure"]),
        "observation.achieved_goal": rows(layout["goal_structure"]),
        "observation.desired_goal": rows(layout["goal_structure"]),
    }
    features: dict[str, Any] = {}
    for column, values in frames.items():
        feature: dict[str, Any] = {
            "dtype": str(values.dtype),
            "shape": list(values.shape[1:]) or [1],
            "names": names.get(column),
        }
        name = column.removeprefix("observation.")
        if name in layout["observation_structure"]:
            feature["names"] = rows({name: layout["observation_structure"][name]})
            if (u := unit(name)) is not None:
                feature["unit"] = u
        features[column] = feature
    return features


def _stats(frames: Mapping[str, np.ndarray]) -> dict[str, dict[str, list[float] | list[int]]]:
    """meta/stats.json: per feature, min, max, mean, std (per row of a vector) and count (frames)."""
    stats: dict[str, dict[str, list[float] | list[int]]] = {}
    for column, values in frames.items():
        if not len(values):
            continue
        v = values.astype(np.float64).reshape(len(values), -1)
        stats[column] = {
            "min": v.min(axis=0).tolist(),
            "max": v.max(axis=0).tolist(),
            "mean": v.mean(axis=0).tolist(),
            "std": v.std(axis=0).tolist(),
            "count": [len(v)],
        }
    return stats


def _arrow(pa: Any, values: np.ndarray) -> Any:
    """A pyarrow column: scalars as they are, (rows, width) as fixed-size lists of width."""
    if values.ndim == 1:
        return pa.array(values)
    width = values.shape[1]
    return pa.FixedSizeListArray.from_arrays(pa.array(np.ascontiguousarray(values).reshape(-1)), width)


def _fps(dt: float) -> int | float:
    """Frames per second of a control period dt [s]: an integer where 1/dt is one (25 for 0.04 s)."""
    fps = 1.0 / dt
    return round(fps) if abs(fps - round(fps)) < 1e-9 else fps


def _written_by_tsrl(path: Path) -> bool:
    try:
        return isinstance(_read_info(path).get(META_KEY), dict)
    except LeRobotDemoError:
        return False


def import_pyarrow() -> tuple[Any, Any]:
    """(pyarrow, pyarrow.parquet), or one line saying how to install them."""
    try:
        import pyarrow
        import pyarrow.parquet
    except ImportError:
        raise InvalidConfig(_INSTALL) from None
    return pyarrow, pyarrow.parquet
