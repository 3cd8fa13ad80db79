"""A run folder: its file names, reading its config and progress, its checkpoints, and its lock.

```
<out_dir>/<env>__<obs>__<action>__<algo>__s<seed>/
    config.json        the exact, validated TrainConfig
    task/              copies of the files its task reads and their sha256s (tsrl.agents.task_record)
    progress.csv       one row per evaluation: env_steps, episodes, wall_time_s (training + evaluation,
                       summed over resumed sessions), eval_time_s (its evaluation part),
                       eval_success_rate, eval_final_distance_m, train_success_rate, critic_loss, actor_loss,
                       eval_penalised_rate (share of evaluation episodes with a penalised step; empty
                       for tasks without penalties and in runs started before it was recorded)
    tb/                TensorBoard logs (SB3's train/ and rollout/ values, eval/)
    checkpoints/       the last two complete checkpoints, step_<env steps>/ each: model.zip,
                       replay_buffer.pkl, vecnormalize.pkl, sha256.json (the normaliser's sha256),
                       rng.pkl, state.json (written last)
    learning_curve.png written when the run completes
    train.lock         while a process trains the run: that process's id
```

Nothing here imports torch or stable-baselines3: the CLI checks a run folder before they load.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import fcntl
import json
import os
import sys
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Self

from ..configs import load_table
from ..exceptions import InvalidConfig, TsrlError, is_number
from ..files import replacing, write_atomic
from . import task_record
from .config import TASK_FILE_SUFFIX, TrainConfig

CONFIG_FILE = "config.json"
PROGRESS = "progress.csv"
TENSORBOARD = "tb"
LEARNING_CURVE = "learning_curve.png"
CHECKPOINTS = "checkpoints"
LOCK = "train.lock"
#: Files of one checkpoint folder; STATE is written last and marks the checkpoint complete.
MODEL = "model.zip"
REPLAY_BUFFER = "replay_buffer.pkl"
NORMALIZER = "vecnormalize.pkl"
#: {file name: sha256} of a checkpoint's files that are checked by hash (the normaliser); absent from
#: checkpoints written before tsrl recorded it.
SHA256S = "sha256.json"
RNG = "rng.pkl"
STATE = "state.json"
#: Complete checkpoints kept: the newest, and one to fall back to if the newest is damaged.
KEEP_CHECKPOINTS = 2
PROGRESS_COLUMNS: tuple[str, ...] = (
    "env_steps",
    "episodes",
    "wall_time_s",
    "eval_time_s",
    "eval_success_rate",
    "eval_final_distance_m",
    "train_success_rate",
    "critic_loss",
    "actor_loss",
    "eval_penalised_rate",
    "gradient_steps",
)


class NotARunFolder(TsrlError):
    """A path that is not a run folder written by `tsrl train`."""

    def __init__(self, path: Path, why: str):
        super().__init__(
            f"{path} is not a run folder ({why}); a run folder holds {CONFIG_FILE} written by `tsrl train`"
        )


class DamagedCheckpoint(TsrlError):
    """A checkpoint file that cannot be used (unreadable, cut short, or counters that disagree)."""

    def __init__(self, path: Path, why: str):
        self.path = path
        self.why = why
        super().__init__(f"{path}: {why}")


class NoUsableCheckpoint(TsrlError):
    """Every checkpoint of a run is damaged; the message names each damaged file."""

    def __init__(self, run_dir: Path, damaged: list[DamagedCheckpoint]):
        super().__init__(
            f"no usable checkpoint in {run_dir}: " + "; ".join(str(d) for d in damaged) + " (nothing changed)"
        )


class RunLocked(TsrlError):
    """Another live process is training the run."""

    def __init__(self, run_dir: Path, pid: str):
        super().__init__(f"{run_dir} is being trained by process {pid}; wait for it or stop it first")


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
    bc_gradient_steps: int = 0
    """A behaviour-cloning run's gradient steps, its clock and budget (its env steps stay 0); 0 for the
    other runs, whose clock is env_steps."""

    @property
    def clock(self) -> int:
        """The run's progress counter: env steps, or a behaviour-cloning run's gradient steps; it names
        the checkpoint folder (checkpoint_path) and schedules evaluations and checkpoints."""
        return self.env_steps + self.bc_gradient_steps


#: AgentConfig fields added after runs were written, with the value those runs ran with: the task's
#: reward (reward_scale 1) and no return bound.
AGENT_FIELDS_ADDED = {"reward_scale": 1.0, "return_bound": 0.0}


def load_config(run_dir: Path | str) -> TrainConfig:
    """The TrainConfig of a run folder (validated; a task file that is gone through the run's copy)."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise NotARunFolder(run_dir, "no such folder")
    path = run_dir / CONFIG_FILE
    if not path.is_file():
        raise NotARunFolder(run_dir, f"no {CONFIG_FILE}")
    try:
        data = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise NotARunFolder(run_dir, f"{CONFIG_FILE} is not valid JSON: {err}") from None
    agent = data.get("agent") if isinstance(data, dict) else None
    if isinstance(agent, dict):  # written before a field: what it ran with, whatever its preset is now
        for key, value in AGENT_FIELDS_ADDED.items():
            agent.setdefault(key, value)
    env_id = data.get("env_id") if isinstance(data, dict) else None
    gone = isinstance(env_id, str) and env_id.endswith(TASK_FILE_SUFFIX) and not Path(env_id).is_file()
    copy = task_record.task_copy(run_dir)[0] if gone else None
    if copy is None:
        return load_table(TrainConfig, data, source=path)
    # Its task file is gone: the config is checked on the run's copy of it (with_task_copy builds the
    # run's environments from the copy) and keeps the file's path, the run's identity.
    cfg = load_table(TrainConfig, data | {"env_id": str(copy)}, source=path)
    object.__setattr__(cfg, "env_id", env_id)
    return cfg


def write_task_record(run_dir: Path, cfg: TrainConfig) -> None:
    """Copies of the files the run's task reads and their sha256s, in run_dir/task/ (tsrl.agents.task_record);
    nothing for environments outside tsrl."""
    if cfg.is_task_file:
        task: str | None = cfg.env_id
    elif cfg.is_tsrl_env:
        import gymnasium as gym

        task = gym.spec(cfg.env_id).kwargs.get("task")
    else:
        task = None
    if isinstance(task, str):
        task_record.write_record(run_dir / task_record.TASK_DIR, task_record.task_files(task))


def with_task_copy(run_dir: Path, cfg: TrainConfig, notify: bool = True) -> TrainConfig:
    """`cfg`, the run's config.json, as the run trains and is evaluated: a task file's run on its copy
    in run_dir/task/ (tsrl.agents.task_record). `notify`: one line on stderr per recorded file that
    changed since the run started, or saying that the run has no record (it then reads its files as
    they are now)."""
    if not cfg.is_tsrl_env:
        return cfg
    copy, notices = task_record.task_copy(run_dir)
    if notify:
        for line in notices:
            print(f"tsrl: notice: {line}", file=sys.stderr)
    return cfg if copy is None or not cfg.is_task_file else dataclasses.replace(cfg, env_id=str(copy))


def run_config(run_dir: Path | str, notify: bool = True) -> TrainConfig:
    """`load_config` on the run's recorded task (`with_task_copy`)."""
    return with_task_copy(Path(run_dir), load_config(run_dir), notify)


def read_progress(run_dir: Path | str) -> list[dict[str, float]]:
    """progress.csv as a list of rows (floats; NaN for empty cells)."""
    path = Path(run_dir) / PROGRESS
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: _to_float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def check_progress(run_dir: Path | str) -> None:
    """Raises InvalidConfig (one line naming the file and row) where progress.csv has a row cut short
    (a kill during a write) or a clock that is not a whole number; read_progress would read it as NaN."""
    path = Path(run_dir) / PROGRESS
    if not path.is_file():
        return
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        for line, row in enumerate(reader, start=2):
            extra = row.pop(None, [])  # DictReader keeps cells past the header under None
            cells = sum(v is not None for v in row.values()) + len(extra)
            if cells != len(row):
                raise InvalidConfig(
                    f"{path}: row {line} has {cells} cells, the header {len(row)} columns (cut short, e.g. "
                    "by a kill during a write); accepted: complete rows (tsrl train --resume drops rows "
                    "after the last checkpoint, or remove the row)"
                )
            clock = (row.get("env_steps") or "").strip()
            if not clock.isdigit():
                raise InvalidConfig(f"{path}: row {line}: env_steps = {clock!r}; accepted: a whole number")


def truncate_progress(run_dir: Path, last_step: int, column: str = "env_steps") -> int:
    """Keeps progress.csv's header and its rows whose `column` (the run's clock: env_steps, or
    gradient_steps for behaviour cloning) is at or before `last_step` (the checkpoint's); drops rows
    after it and a torn last line. Returns the clock of the last row kept (-1 if none)."""
    path = run_dir / PROGRESS
    if not path.is_file():
        return -1
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    kept = [
        r
        for r in rows
        if (r.get(column) or "").isdigit() and int(r[column]) <= last_step and None not in r.values()
    ]
    with replacing(path) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=PROGRESS_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(kept)
    return int(kept[-1][column]) if kept else -1


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Writes `data` as indented JSON to `path` atomically (tsrl.files.write_atomic)."""
    write_atomic(path, json.dumps(data, indent=2) + "\n")


def checkpoint_path(run_dir: Path, clock: int) -> Path:
    """The folder of the checkpoint at `clock` (RunState.clock: env steps, or BC's gradient steps)."""
    return run_dir / CHECKPOINTS / f"step_{clock:010d}"


def checkpoint_dirs(run_dir: Path | str) -> list[Path]:
    """The checkpoint folders of a run, oldest first (not verified).

    Each was renamed into place whole, so every one is complete unless damaged afterwards.
    """
    root = Path(run_dir) / CHECKPOINTS
    if not root.is_dir():
        return []
    dirs = [p for p in root.glob("step_*") if p.is_dir() and p.name.removeprefix("step_").isdigit()]
    return sorted(dirs, key=lambda p: int(p.name.removeprefix("step_")))


def latest_checkpoint(run_dir: Path | str) -> Path | None:
    """The checkpoint with the most env steps (not verified), None if there is none."""
    dirs = checkpoint_dirs(run_dir)
    return dirs[-1] if dirs else None


def read_state(checkpoint: Path) -> RunState:
    """The counters of a checkpoint; DamagedCheckpoint if state.json is unreadable or disagrees with
    the checkpoint's folder name."""
    path = checkpoint / STATE
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DamagedCheckpoint(path, f"unreadable ({type(err).__name__}: {err})") from None
    names = [f.name for f in fields(RunState)]
    if not isinstance(data, dict) or not set(names[:5]) <= set(data) <= set(names):
        raise DamagedCheckpoint(path, f"not a checkpoint state; expected keys {', '.join(names)}")
    if any(not is_number(v) or v < 0 for v in data.values()):
        raise DamagedCheckpoint(path, f"counters must be numbers >= 0; got {data}")
    state = RunState(**data)
    if checkpoint.name != f"step_{state.clock:010d}":
        counter = "bc_gradient_steps" if state.bc_gradient_steps else "env_steps"
        raise DamagedCheckpoint(path, f"{counter} {state.clock} disagrees with the folder {checkpoint.name}")
    return state


class RunLock:
    """`with RunLock(run_dir):` one training process per run folder.

    The lock is an flock on `train.lock`, which holds the owner's process id. The kernel releases it
    when its process ends, however it ends, so a lock left by a killed process never blocks. Entering
    raises RunLocked, naming the owner's process id, while a live process holds it.
    """

    def __init__(self, run_dir: Path):
        self.path = run_dir / LOCK
        self.fd: int | None = None

    def __enter__(self) -> Self:
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                pid = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise RunLocked(self.path.parent, pid) from None
            with contextlib.suppress(FileNotFoundError):
                if os.fstat(fd).st_ino == os.stat(self.path).st_ino:
                    break  # still the file at the path: not one its previous owner just removed
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self.fd = fd
        return self

    def __exit__(self, *exc: object) -> None:
        if self.fd is not None:
            self.path.unlink(missing_ok=True)
            os.close(self.fd)
            self.fd = None


def check_not_locked(run_dir: Path) -> None:
    """Raises RunLocked if a live process trains `run_dir` (without taking the lock)."""
    if (run_dir / LOCK).is_file():
        with RunLock(run_dir):
            pass


def _to_float(value: str | None) -> float:
    try:
        return float(value) if value not in (None, "") else float("nan")
    except ValueError:
        return float("nan")
