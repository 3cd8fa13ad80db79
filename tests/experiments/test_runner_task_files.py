"""A run of a task file is recognised by its files' contents, not by the path it was read from: the
same experiment run from another checkout (another path, the same bytes) finds its finished runs."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tsrl.agents.config import TrainConfig
from tsrl.agents.run_folder import CONFIG_FILE, write_json_atomic, write_task_record
from tsrl.exceptions import InvalidConfig
from tsrl.experiments.runner import run_state

REPO = Path(__file__).resolve().parents[2]
TASK = REPO / "experiments" / "tasks" / "reach-2cm.toml"


def checkout(root: Path) -> Path:
    """A copy of the task file under `root` (as another clone of the repository holds it)."""
    root.mkdir()
    return Path(shutil.copy(TASK, root / TASK.name))


def started_run(cfg: TrainConfig, exp_dir: Path) -> Path:
    """A run folder as training starts it: the task record, then config.json (no checkpoint yet)."""
    run_dir = exp_dir / cfg.run_name
    run_dir.mkdir(parents=True)
    write_task_record(run_dir, cfg)
    write_json_atomic(run_dir / CONFIG_FILE, cfg.to_dict())
    return run_dir


def test_the_same_task_file_from_another_path_is_the_same_run_and_a_changed_one_is_not(tmp_path):
    first, second = checkout(tmp_path / "first"), checkout(tmp_path / "second")
    ours = TrainConfig(env_id=str(first), seed=0, total_timesteps=300)
    theirs = TrainConfig(env_id=str(second), seed=0, total_timesteps=300)
    assert ours.run_name == theirs.run_name and ours.env_id != theirs.env_id
    run_dir = started_run(ours, tmp_path / "results")

    assert run_state(ours, run_dir) == "partial"
    assert run_state(theirs, run_dir) == "partial"  # the same bytes from the other checkout

    other_seed = TrainConfig(env_id=str(second), seed=1, total_timesteps=300)
    with pytest.raises(InvalidConfig, match="another config") as err:
        run_state(other_seed, run_dir)  # every other key still counts
    assert "seed: 0 there, 1 here" in str(err.value) and "env_id" not in str(err.value)

    second.write_text(second.read_text().replace("position = 0.02", "position = 0.03"))
    with pytest.raises(InvalidConfig, match="another config.*env_id"):
        run_state(theirs, run_dir)  # the other checkout's task file has changed
