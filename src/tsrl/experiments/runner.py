"""One run of an experiment: train it, resume it, or skip it when finished; a failure is saved, not raised.

The run folder is the training layer's (`<experiment dir>/<cfg.run_name>/`, see tsrl.agents.training);
the runner adds `train.log` (the run's console output) and, when the run fails, `error.txt` (the
traceback). A later `tsrl experiment` retries a failed run from its latest checkpoint.
"""

from __future__ import annotations

import contextlib
import math
import signal
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..agents.config import TrainConfig
from ..agents.run_folder import (
    CONFIG_FILE,
    DamagedCheckpoint,
    checkpoint_dirs,
    load_config,
    read_progress,
    read_state,
)
from ..agents.task_record import records_files_of
from ..agents.training import TrainingInterrupted, resume, train
from ..exceptions import InvalidConfig

ERROR_FILE = "error.txt"
LOG_FILE = "train.log"

RunStatus = Literal["trained", "resumed", "skipped", "failed", "interrupted"]


@dataclass(frozen=True)
class RunOutcome:
    """What happened to one run of an experiment."""

    run_name: str
    status: RunStatus
    """trained (from scratch), resumed (from a checkpoint, or to a larger budget), skipped (already at
    its budget), failed (error.txt in its folder), interrupted (stopped on a signal; resumable)."""
    env_steps: int
    """Env steps of the run's latest checkpoint after this call (0 if none)."""
    seconds: float
    """Wall time of this call."""
    success: float = math.nan
    """Last evaluation's success rate (NaN if none)."""
    error: str = ""
    """One line: why the run failed or stopped."""


def checkpoint_steps(run_dir: Path) -> int:
    """Env steps of the run's latest checkpoint with a readable state.json (0 if it has none)."""
    for checkpoint in reversed(checkpoint_dirs(run_dir)):
        with contextlib.suppress(DamagedCheckpoint):
            return read_state(checkpoint).env_steps
    return 0


def run_state(cfg: TrainConfig, run_dir: Path) -> Literal["new", "finished", "partial"]:
    """new: no run in the folder; finished: its latest checkpoint reached `cfg`'s budget; partial: it
    has to be resumed (interrupted, failed, or a budget raised since).

    Raises InvalidConfig if the folder holds a run of another config (anything but the budget differs;
    a task file is the same when its files' contents are, from whichever path: another checkout's).
    """
    if not (run_dir / CONFIG_FILE).is_file():
        return "new"
    diff = config_difference(cfg, run_dir)
    if diff:
        raise InvalidConfig(
            f"run folder {run_dir} holds a run of another config ({diff}); move it away or use another --out-dir"
        )
    return "finished" if checkpoint_steps(run_dir) >= cfg.total_timesteps else "partial"


def config_difference(cfg: TrainConfig, run_dir: Path) -> str:
    """How the run in `run_dir` differs from `cfg` beyond its budget ("key: theirs there, ours here",
    comma-separated); "" where it does not or the folder holds no run."""
    if not (run_dir / CONFIG_FILE).is_file():
        return ""
    existing = load_config(run_dir)
    theirs, ours = existing.to_dict(), cfg.to_dict()
    theirs.pop("total_timesteps")
    ours.pop("total_timesteps")
    if (
        existing.is_task_file
        and cfg.is_task_file
        and theirs["env_id"] != ours["env_id"]
        and records_files_of(run_dir, cfg.env_id)
    ):
        theirs["env_id"] = ours["env_id"]
    return ", ".join(f"{k}: {theirs[k]!r} there, {ours[k]!r} here" for k in ours if theirs[k] != ours[k])


def run_one(cfg: TrainConfig, exp_dir: Path | str) -> RunOutcome:
    """Brings the run of `cfg` in `exp_dir` to its budget: trains it, resumes it, or skips it.

    Never raises for a failing run (a worker must go on with the others): the outcome says what
    happened and `error.txt` in the run folder holds the traceback.
    """
    run_dir = Path(exp_dir) / cfg.run_name
    t0 = time.monotonic()
    status: RunStatus = "failed"
    try:
        state = run_state(cfg, run_dir)
        if state == "finished":
            status = "skipped"
        else:
            run_dir.mkdir(parents=True, exist_ok=True)
            (run_dir / ERROR_FILE).unlink(missing_ok=True)
            with (
                open(run_dir / LOG_FILE, "a") as log,
                contextlib.redirect_stdout(log),
                contextlib.redirect_stderr(log),
            ):
                if state == "new":
                    train(cfg, exp_dir, progress_bar=False)
                    status = "trained"
                else:
                    resume(run_dir, total_timesteps=cfg.total_timesteps, progress_bar=False)
                    status = "resumed"
        error = ""
    except TrainingInterrupted as stop:
        name = signal.Signals(stop.signum).name
        status, error = "interrupted", f"{name}: stopped at {stop.env_steps} env steps, checkpoint saved"
    except Exception as err:  # noqa: BLE001  (reported in the outcome and error.txt; the others go on)
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / ERROR_FILE).write_text(traceback.format_exc())
        status, error = "failed", f"{type(err).__name__}: {err}".splitlines()[0]
    return RunOutcome(
        run_name=cfg.run_name,
        status=status,
        env_steps=checkpoint_steps(run_dir) if run_dir.is_dir() else 0,
        seconds=time.monotonic() - t0,
        success=last_success(run_dir),
        error=error,
    )


def last_success(run_dir: Path) -> float:
    """Success rate of the run's last evaluation (NaN if none)."""
    rows = read_progress(run_dir)
    return rows[-1]["eval_success_rate"] if rows else math.nan
