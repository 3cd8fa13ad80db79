"""A run's record of the files its task reads, in `<run>/task/` (written and read through
tsrl.agents.run_folder: write_task_record, with_task_copy, run_config).

```
<run>/task/
    record.json    {"files": [{"roles": ["task"], "name": ..., "path": ..., "sha256": ..., "copy": ...}, ...]}
    <task>.toml    the task file, byte for byte
    <robot>.toml   its robot file (a task on a robot file)
    <model>.xml    each model file it reads: the task's scene, the robot's model
```

The files are the task file (a built-in task's own TOML), its robot file, the robot's model file and
the task's scene file. Files installed with tsrl or another package (built-in tasks, robots and
scenes; `pkg://` models) are recorded by their sha256 and not copied: a changed installation is
noticed, not undone. A model's own includes, meshes and textures are neither copied nor recorded.

A resumed or evaluated run builds its task from the record (`recorded_task`): the task and robot
files from their copies, a model file where it lies while its bytes are the recorded ones (so that
its includes and meshes resolve) and from its copy once it has changed or gone. Each recorded file
that differs from its record is one line of notice (`task_copy`).

Imports nothing of tsrl.agents (TrainConfig finds a run's copy through `recorded_task`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..assets import SCENES, scene_path
from ..envs.tasks import BUILTIN_TASKS, Task, builtin_task_path, load_task
from ..files import write_atomic
from ..model_files import is_package_path, resolve_model_path
from ..robots import ROBOTS, load_robot

#: The folder of a run's task files and their record.
TASK_DIR = "task"
RECORD = "record.json"
_ROW_KEYS = frozenset({"roles", "path", "sha256", "copy"})


@dataclass(frozen=True)
class TaskFile:
    """One file a task reads."""

    roles: tuple[str, ...]
    """What it is to the task: task, robot, robot model, scene (one file may be several)."""
    name: str
    """The file as it is named: a path, a built-in task or scene, a `pkg://` model."""
    path: Path
    """The file read (absolute)."""
    installed: bool
    """Installed with tsrl or another package: recorded, not copied."""


def task_files(task: str | Path) -> list[TaskFile]:
    """The files that `task` (a built-in task's name or a task file) reads, the task file first."""
    found: dict[Path, TaskFile] = {}

    def add(role: str, name: str, path: Path, installed: bool) -> None:
        path = path.resolve()
        known = found.get(path)
        roles = (*known.roles, role) if known is not None else (role,)
        found[path] = TaskFile(roles, name, path, installed)

    loaded = load_task(task)
    builtin = isinstance(task, str) and task in BUILTIN_TASKS
    add("task", str(task), builtin_task_path(str(task)) if builtin else Path(task), installed=builtin)
    if loaded.robot in ROBOTS:
        robot = ROBOTS[loaded.robot]
    else:
        add("robot", loaded.robot, Path(loaded.robot_path), installed=False)
        robot = load_robot(loaded.robot_path)  # its model's path resolved against the robot file
    for role, model, base in (
        ("robot model", robot.model, None),
        ("scene", loaded.scene, loaded.source.parent if loaded.source is not None else None),
    ):
        if model in SCENES:
            add(role, model, scene_path(model), installed=True)
        else:
            add(role, model, resolve_model_path(model, base, key=role), installed=is_package_path(model))
    return list(found.values())


def write_record(folder: Path, files: list[TaskFile]) -> None:
    """Copies `files` into `folder` (installed ones: their sha256 only), then writes the record; every
    file atomically (tsrl.files.write_atomic), the record last."""
    folder.mkdir(exist_ok=True)
    rows: list[dict[str, Any]] = []
    used: set[str] = {RECORD}
    for f in files:
        data = f.path.read_bytes()
        copy = None
        if not f.installed:
            copy = _free_name(f.path, used)
            write_atomic(folder / copy, data)
        rows.append(
            {
                "roles": list(f.roles),
                "name": f.name,
                "path": str(f.path),
                "sha256": hashlib.sha256(data).hexdigest(),
                "copy": copy,
            }
        )
    write_atomic(folder / RECORD, json.dumps({"files": rows}, indent=2) + "\n")


def task_copy(run_dir: Path) -> tuple[Path | None, list[str]]:
    """The run's copy of its task file (None for a built-in task's run, or without a record) and one
    line per recorded file that differs from its record, or why there is no record."""
    rows, problem = read_record(run_dir)
    if rows is None:
        return None, [f"{run_dir} {problem}; it reads its task's files as they are now"]
    row = _row(rows, "task")
    copy = run_dir / TASK_DIR / row["copy"] if row is not None and row["copy"] is not None else None
    return copy, _changes(run_dir, rows)


def records_files_of(run_dir: Path, task: str | Path) -> bool:
    """Whether the run's record holds the files that `task` reads now, by role and content (sha256),
    wherever they lie: the same task file read from another checkout's path is the same task."""
    rows, _ = read_record(run_dir)
    if rows is None:
        return False
    recorded = sorted((tuple(row["roles"]), row["sha256"]) for row in rows)
    return recorded == sorted((f.roles, _sha256(f.path)) for f in task_files(task))


def recorded_task(path: str | Path) -> Task | None:
    """The Task of a task file copied into a run's task folder, its robot file from its copy and its
    scene as `with_task_copy` reads it (where it lies while unchanged, else its copy); None for any
    other task file."""
    path = Path(path)
    folder = path.parent
    if folder.name != TASK_DIR or not (folder / RECORD).is_file():
        return None
    rows, _ = read_record(folder.parent)
    task_row = _row(rows or [], "task")
    if rows is None or task_row is None or task_row["copy"] != path.name:
        return None
    task = load_task(path)
    changes: dict[str, Any] = {}
    robot = _row(rows, "robot")
    if task.robot not in ROBOTS and robot is not None and robot["copy"] is not None:
        changes["robot"] = str(folder / robot["copy"])
    scene = _row(rows, "scene")
    if task.scene not in SCENES and not is_package_path(task.scene) and scene is not None:
        unchanged = _sha256(Path(scene["path"])) == scene["sha256"]
        changes["scene"] = (
            scene["path"] if unchanged or scene["copy"] is None else str(folder / scene["copy"])
        )
    return dataclasses.replace(task, **changes) if changes else task


def _changes(run_dir: Path, rows: list[dict[str, Any]]) -> list[str]:
    """One line per recorded file whose bytes are not the recorded ones."""
    lines = []
    for row in rows:
        now = _sha256(Path(row["path"]))
        if now == row["sha256"]:
            continue
        what = f"{row['path']} ({', '.join(row['roles'])}{', installed' if row['copy'] is None else ''})"
        how = "is gone" if now is None else "changed since the run started"
        if row["copy"] is None:
            lines.append(f"{what} {how} (another tsrl or package?); the run reads it as it is now")
        else:
            lines.append(f"{what} {how}; the run uses its copy {run_dir / TASK_DIR / row['copy']}")
    return lines


def read_record(run_dir: Path) -> tuple[list[dict[str, Any]] | None, str]:
    """The rows of a run's record, or None and why there are none."""
    path = run_dir / TASK_DIR / RECORD
    if not path.is_file():
        return None, "has no record of its task's files (a run from before tsrl kept one)"
    try:
        rows = json.loads(path.read_text())["files"]
        missing = [row for row in rows if not _ROW_KEYS <= set(row)]
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, KeyError, TypeError) as err:
        return None, f"has an unreadable {path.relative_to(run_dir)} ({type(err).__name__}: {err})"
    if missing:
        return (
            None,
            f"has an unreadable {path.relative_to(run_dir)} (a file without {', '.join(sorted(_ROW_KEYS))})",
        )
    return rows, ""


def _row(rows: list[dict[str, Any]], role: str) -> dict[str, Any] | None:
    return next((row for row in rows if role in row["roles"]), None)


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _free_name(path: Path, used: set[str]) -> str:
    """`path`'s file name, or <stem>-2<suffix>, ... where an earlier copy has it."""
    name, n = path.name, 1
    while name in used:
        n += 1
        name = f"{path.stem}-{n}{path.suffix}"
    used.add(name)
    return name
