"""train() and resume(): one run in a self-describing, resumable folder.

```
<out_dir>/<env>__<obs>__<action>__<algo>__s<seed>/
    config.json        the exact, validated TrainConfig
    progress.csv       one row per evaluation: env_steps, episodes, wall_time_s (training + evaluation,
                       summed over resumed sessions), eval_time_s (its evaluation part),
                       eval_success_rate, eval_final_distance_m, train_success_rate, critic_loss, actor_loss
    tb/                TensorBoard logs (SB3's train/ and rollout/ values, eval/)
    checkpoints/       latest model, replay buffer, normaliser statistics, counters, RNG states
    demos.json         with demonstrations: their file's absolute path, sha256 and size
    learning_curve.png written when the run completes
```

Evaluations and checkpoints happen at "safe points": after an update, where the next episode starts.
SIGINT and SIGTERM are noted and honoured at the next safe point (at most one update period later):
a checkpoint is written and TrainingInterrupted raised. A second SIGINT stops at once, without one.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any, Self

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from ..exceptions import InvalidConfig
from .checkpoint import RunState, latest_checkpoint, load_checkpoint, read_state, save_checkpoint
from .config import CONFIG_FILE, TrainConfig, from_dict, load_config
from .demos import DEMOS_RECORD, attach_bc_loss, check_demo_record, demo_record
from .evaluation import Evaluator, eval_seeds
from .factory import ALGOS, buffer_capacity, make_agent, make_vec_env

CONFIG = CONFIG_FILE
PROGRESS = "progress.csv"
TENSORBOARD = "tb"
LEARNING_CURVE = "learning_curve.png"
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
)


class TrainingInterrupted(Exception):
    """Training stopped on SIGINT/SIGTERM after saving a checkpoint; resume with `tsrl train --resume`."""

    def __init__(self, signum: int, run_dir: Path, env_steps: int):
        self.signum = signum
        self.run_dir = run_dir
        self.env_steps = env_steps
        name = signal.Signals(signum).name
        super().__init__(
            f"{name}: stopped at {env_steps} env steps, checkpoint saved; "
            f"continue with: tsrl train --resume {run_dir}"
        )


def train(cfg: TrainConfig, out_dir: Path | str, progress_bar: bool = True) -> Path:
    """Trains a new run in `out_dir/<cfg.run_name>`; returns the run folder.

    Raises InvalidConfig if the folder already holds a run (resume it instead).
    """
    run_dir = Path(out_dir) / cfg.run_name
    if (run_dir / CONFIG).exists():
        raise InvalidConfig(
            f"run folder {run_dir} already exists; continue it with `tsrl train --resume {run_dir}` "
            "or choose another --out-dir"
        )
    session = _Session(cfg, run_dir, progress_bar)  # builds the envs first: bad obs/action fail here
    demos = demo_record(cfg)  # a bad demonstration file fails here, before the run folder exists
    run_dir.mkdir(parents=True, exist_ok=True)
    _write_json_atomic(run_dir / CONFIG, cfg.to_dict())
    if demos is not None:
        _write_json_atomic(run_dir / DEMOS_RECORD, demos)
    session.run(checkpoint=None)
    return run_dir


def resume(run_dir: Path | str, total_timesteps: int | None = None, progress_bar: bool = True) -> Path:
    """Continues a run from its latest checkpoint (or from scratch if it has none), optionally with a
    new budget; counters, replay buffer and normaliser statistics come back."""
    run_dir = Path(run_dir)
    cfg = load_config(run_dir)
    checkpoint = latest_checkpoint(run_dir)
    done = read_state(checkpoint).env_steps if checkpoint is not None else 0
    if total_timesteps is not None and total_timesteps < done:
        raise InvalidConfig(f"--total-timesteps {total_timesteps} is below the {done} env steps already done")
    if total_timesteps is not None and total_timesteps != cfg.total_timesteps:
        cfg = from_dict(TrainConfig, cfg.to_dict() | {"total_timesteps": total_timesteps})
        _write_json_atomic(run_dir / CONFIG, cfg.to_dict())
    if checkpoint is None:  # restarts from scratch: the demonstrations must be the recorded ones
        check_demo_record(run_dir, cfg)
    session = _Session(cfg, run_dir, progress_bar)
    session.run(checkpoint=checkpoint)
    return run_dir


def read_progress(run_dir: Path | str) -> list[dict[str, float]]:
    """progress.csv as a list of rows (floats; NaN for empty cells)."""
    path = Path(run_dir) / PROGRESS
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [{k: _to_float(v) for k, v in row.items()} for row in csv.DictReader(f)]


class _Session:
    """One process's share of a run: envs, model, evaluator, progress file, signal handling."""

    def __init__(self, cfg: TrainConfig, run_dir: Path, progress_bar: bool):
        self.cfg = cfg
        self.run_dir = run_dir
        self.progress_bar = progress_bar
        th.set_num_threads(cfg.torch_threads)
        self.venv: VecEnv = make_vec_env(cfg)
        self.normalizer = self.venv if isinstance(self.venv, VecNormalize) else None
        self.evaluator = Evaluator(cfg, eval_seeds(cfg.seed, cfg.eval_episodes))
        self.stop_signal: int | None = None

    def run(self, checkpoint: Path | None) -> None:
        cfg = self.cfg
        try:
            if checkpoint is None:
                model = make_agent(cfg, self.venv)
                state = RunState(0, 0, 0.0, 0, cfg.checkpoint_freq)
            else:
                model, state = load_checkpoint(checkpoint, ALGOS[cfg.agent.algo], self.venv, self.normalizer)
                episode_steps = int(self.venv.get_attr("spec")[0].max_episode_steps)
                model.replay_buffer.grow(buffer_capacity(cfg, episode_steps))  # a larger budget on resume
                model.buffer_size = model.replay_buffer.buffer_size
                if cfg.agent.demos.enabled:  # the demonstrations came back in the replay buffer
                    attach_bc_loss(model, cfg.agent.demos)
                # The env restarts with a new episode, seeded from (seed, episodes done).
                self.venv.seed(int(np.random.SeedSequence([cfg.seed, state.episodes]).generate_state(1)[0]))
            last_row = _truncate_progress(self.run_dir / PROGRESS, state.env_steps if checkpoint else -1)
            model.set_logger(configure(str(self.run_dir / TENSORBOARD), ["tensorboard"]))
            callback = _SafePointCallback(self, state, last_row)
            remaining = cfg.total_timesteps - model.num_timesteps
            with _SignalCatcher(self):
                if remaining > 0:
                    model.learn(remaining, callback=callback, reset_num_timesteps=False, log_interval=10)
                else:
                    callback.init_callback(model)
                    callback.on_training_end()
            model.logger.close()
            callback.close()
            _summary(self.run_dir, callback)
        finally:
            self.evaluator.close()
            self.venv.close()


class _SignalCatcher:
    """SIGINT/SIGTERM set session.stop_signal; a second SIGINT raises KeyboardInterrupt at once."""

    def __init__(self, session: _Session):
        self.session = session
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> Self:
        if _in_main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum: int, frame: Any) -> None:
        if self.session.stop_signal is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.session.stop_signal = signum
        print(f"\n{signal.Signals(signum).name}: stopping at the next update boundary...", file=sys.stderr)

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)


class _SafePointCallback(BaseCallback):
    """Evaluates, writes progress rows and checkpoints between updates; drives the progress bar."""

    def __init__(self, session: _Session, state: RunState, last_eval_step: int):
        super().__init__()
        self.session = session
        self.cfg = session.cfg
        self.next_eval = state.next_eval
        self.next_checkpoint = state.next_checkpoint
        self.wall_base = state.wall_time_s
        self.eval_time = state.eval_time_s
        self.t0 = time.monotonic()
        self.last_eval_step = last_eval_step
        self.last_success = float("nan")
        self.pbar: Any = None
        self.progress_file = open(session.run_dir / PROGRESS, "a", newline="")  # noqa: SIM115
        self.writer = csv.DictWriter(self.progress_file, fieldnames=PROGRESS_COLUMNS)
        if self.progress_file.tell() == 0:
            self.writer.writeheader()
            self.progress_file.flush()

    def wall_time(self) -> float:
        return self.wall_base + time.monotonic() - self.t0

    def _on_training_start(self) -> None:
        if self.session.progress_bar:
            from tqdm import tqdm

            self.pbar = tqdm(
                total=self.cfg.total_timesteps,
                initial=self.model.num_timesteps,
                unit="step",
                dynamic_ncols=True,
                mininterval=0.5,
                file=sys.stderr,
            )
            self._update_postfix()

    def _on_rollout_start(self) -> None:
        self._safe_point(final=False)

    def _on_step(self) -> bool:
        if self.pbar is not None:
            self.pbar.update(self.training_env.num_envs)
            if any(self.locals.get("dones", ())):
                self._update_postfix()
        return True

    def _on_training_end(self) -> None:
        self._safe_point(final=True)

    def close(self) -> None:
        if self.pbar is not None:
            self.pbar.close()
            self.pbar = None
        self.progress_file.close()

    def _update_postfix(self) -> None:
        if self.pbar is None:
            return
        self.pbar.set_postfix(
            episodes=self.model._episode_num,
            eval_success=f"{self.last_success:.2f}",
            train_success=f"{_train_success(self.model):.2f}",
            refresh=False,
        )

    def _safe_point(self, final: bool) -> None:
        model: OffPolicyAlgorithm = self.model
        step = model.num_timesteps
        stop = self.session.stop_signal
        if (step >= self.next_eval or final) and step != self.last_eval_step and stop is None:
            self._evaluate(model, step)
            self.next_eval = (step // self.cfg.eval_freq + 1) * self.cfg.eval_freq
        if step >= self.next_checkpoint or final or stop is not None:
            self.next_checkpoint = (step // self.cfg.checkpoint_freq + 1) * self.cfg.checkpoint_freq
            state = RunState(
                step,
                model._episode_num,
                self.wall_time(),
                self.next_eval,
                self.next_checkpoint,
                self.eval_time,
            )
            save_checkpoint(self.session.run_dir, model, self.session.normalizer, state)
        if stop is not None:
            model.logger.close()
            self.close()
            raise TrainingInterrupted(stop, self.session.run_dir, step)

    def _evaluate(self, model: OffPolicyAlgorithm, step: int) -> None:
        t0 = time.monotonic()
        result = self.session.evaluator.evaluate(model, self.session.normalizer)
        self.eval_time += time.monotonic() - t0
        losses = model.logger.name_to_value
        row = {
            "env_steps": step,
            "episodes": model._episode_num,
            "wall_time_s": f"{self.wall_time():.3f}",
            "eval_time_s": f"{self.eval_time:.3f}",
            "eval_success_rate": f"{result.success_rate:.4f}",
            "eval_final_distance_m": f"{result.mean_final_distance:.5f}",
            "train_success_rate": _fmt(_train_success(model)),
            "critic_loss": _fmt(losses.get("train/critic_loss")),
            "actor_loss": _fmt(losses.get("train/actor_loss")),
        }
        self.writer.writerow(row)
        self.progress_file.flush()
        model.logger.record("eval/success_rate", result.success_rate)
        model.logger.record("eval/final_distance_m", result.mean_final_distance)
        model.logger.record("time/episodes", model._episode_num)
        model.logger.dump(step)
        self.last_eval_step = step
        self.last_success = result.success_rate
        self._update_postfix()


def _train_success(model: OffPolicyAlgorithm) -> float:
    buf = model.ep_success_buffer
    return float(np.mean(buf)) if buf else float("nan")


def _fmt(value: float | None) -> str:
    return "" if value is None or not math.isfinite(float(value)) else f"{float(value):.10g}"


def _to_float(value: str | None) -> float:
    try:
        return float(value) if value not in (None, "") else float("nan")
    except ValueError:
        return float("nan")


def _truncate_progress(path: Path, last_step: int) -> int:
    """Keeps the header and the rows at or before `last_step` (the checkpoint); drops torn lines.

    Returns the env steps of the last row kept (-1 if none).
    """
    if not path.is_file():
        return -1
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    kept = [
        r
        for r in rows
        if r.get("env_steps", "").isdigit() and int(r["env_steps"]) <= last_step and None not in r.values()
    ]
    tmp = path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=PROGRESS_COLUMNS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(kept)
    os.replace(tmp, path)
    return int(kept[-1]["env_steps"]) if kept else -1


def _write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    os.replace(tmp, path)


def _summary(run_dir: Path, callback: _SafePointCallback) -> None:
    from .plotting import plot_learning_curves

    plot_learning_curves([run_dir], run_dir / LEARNING_CURVE)
    rows = read_progress(run_dir)
    last = rows[-1] if rows else {}
    print(
        f"run folder: {run_dir}\n"
        f"final: {int(last.get('env_steps', 0))} env steps, {int(last.get('episodes', 0))} episodes, "
        f"eval success {last.get('eval_success_rate', float('nan')):.2f}, "
        f"final distance {last.get('eval_final_distance_m', float('nan')):.3f} m, "
        f"wall time {last.get('wall_time_s', float('nan')):.0f} s\n"
        f"learning curve: {run_dir / LEARNING_CURVE}"
    )


def _in_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()
