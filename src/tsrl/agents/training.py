"""train() and resume(): one run in a self-describing, resumable folder (layout: tsrl.agents.run_folder).

One process trains a run folder at a time (RunLock). Resuming uses the newest checkpoint that passes
verification and falls back to the previous one if it is damaged (tsrl.agents.checkpoint).
Evaluations and checkpoints happen at "safe points": after an update, where the next episode starts.
SIGINT and SIGTERM are noted and honoured after the env step, gradient step or evaluation step in
progress: a rollout stops there (the episode so far is kept as one cut short at a time limit; the
step that saw the signal is neither stored nor counted), an update before its next gradient step
(tsrl.agents.update_stop; the rest of it is dropped), an evaluation before its next step (dropped,
run again on resume). A checkpoint is written and TrainingInterrupted raised. A second SIGINT stops
at once, without one.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import shutil
import signal
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from ..exceptions import InvalidConfig
from ..signals import StopSignals
from .bc import BehaviourCloning
from .checkpoint import DEMO_RESETS, Checkpoint, load_checkpoint, save_checkpoint, usable_checkpoint
from .config import BC, TrainConfig
from .demo_files import DEMOS_RECORD, check_demo_record, demo_record
from .demos import attach_bc_loss, load_run_demos
from .evaluation import EvaluationStopped, Evaluator, eval_seeds
from .factory import ALGO_CLASSES, algo_class, attach_added_losses, buffer_capacity, make_agent, make_vec_env
from .her import FeatureHerReplayBuffer
from .init_from import check_init_from, load_init
from .plotting import plot_learning_curves
from .reference import ReferenceTD3Policy
from .run_folder import (
    CONFIG_FILE,
    LEARNING_CURVE,
    PROGRESS,
    PROGRESS_COLUMNS,
    TENSORBOARD,
    RunLock,
    RunState,
    checkpoint_dirs,
    load_config,
    read_progress,
    truncate_progress,
    with_task_copy,
    write_json_atomic,
    write_task_record,
)
from .update_stop import UpdateStop, UpdateStopped


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
    if (run_dir / CONFIG_FILE).exists():
        raise InvalidConfig(
            f"run folder {run_dir} already exists; continue it with `tsrl train --resume {run_dir}` "
            "or choose another --out-dir"
        )
    check_init_from(cfg)  # a source of another algorithm, size or layout: nothing is written
    session = _Session(cfg, run_dir, progress_bar)  # builds the envs first: bad obs/action fail here
    try:
        demos = demo_record(cfg)  # a bad demonstration file fails here, before the run folder exists
        run_dir.mkdir(parents=True, exist_ok=True)
        with RunLock(run_dir):
            write_task_record(run_dir, cfg)  # copies of the task's files, before config.json
            write_json_atomic(run_dir / CONFIG_FILE, cfg.to_dict())
            if demos is not None:
                write_json_atomic(run_dir / DEMOS_RECORD, demos)
            session.run(checkpoint=None)
    finally:
        session.close()
    return run_dir


def resume(run_dir: Path | str, total_timesteps: int | None = None, progress_bar: bool = True) -> Path:
    """Continues a run from its newest usable checkpoint (or from scratch if it has none), optionally
    with a new budget; counters, replay buffer and normaliser statistics come back.

    Damaged checkpoints newer than the one used are removed before training restarts from it.
    Raises RunLocked while another process trains the run, NoUsableCheckpoint (leaving the folder as
    it was) when every checkpoint is damaged.
    """
    run_dir = Path(run_dir)
    cfg = load_config(run_dir)
    with RunLock(run_dir):
        checkpoint = usable_checkpoint(run_dir, cfg.agent.normalize, for_training=True)
        done = checkpoint.state.env_steps if checkpoint is not None else 0
        if total_timesteps is not None and total_timesteps < done:
            raise InvalidConfig(
                f"--total-timesteps {total_timesteps} is below the {done} env steps already done"
            )
        if checkpoint is not None:  # damaged ones newer than it: the run goes past their steps again
            for newer in checkpoint_dirs(run_dir):
                if newer.name > checkpoint.path.name:
                    shutil.rmtree(newer)
        run = with_task_copy(run_dir, cfg)  # on its recorded task (agents.task_record)
        if total_timesteps is not None and total_timesteps != cfg.total_timesteps:
            run = dataclasses.replace(run, total_timesteps=total_timesteps)
            write_json_atomic(run_dir / CONFIG_FILE, cfg.to_dict() | {"total_timesteps": total_timesteps})
        if checkpoint is None:  # restarts from scratch: the demonstrations must be the recorded ones
            check_demo_record(run_dir, cfg)
        session = _Session(run, run_dir, progress_bar)
        try:
            session.run(checkpoint=checkpoint)
        finally:
            session.close()
    return run_dir


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

    def run(self, checkpoint: Checkpoint | None) -> None:
        cfg = self.cfg
        if checkpoint is None:
            model = make_agent(cfg, self.venv)
            if cfg.init_from is not None:  # the source's networks and normaliser (tsrl.agents.init_from)
                load_init(cfg, self.run_dir, model, self.normalizer)
            state = RunState(0, 0, 0.0, 0, cfg.checkpoint_freq)
        elif cfg.agent.algo == BC:
            model = load_checkpoint(checkpoint, ALGO_CLASSES[BC], self.venv, self.normalizer)
            assert isinstance(model, BehaviourCloning)
            model.set_demos(load_run_demos(cfg.agent.demos, self.venv, None), self.normalizer)
            model._n_updates = checkpoint.state.bc_gradient_steps
            state = checkpoint.state
        else:
            model = load_checkpoint(checkpoint, algo_class(cfg.agent), self.venv, self.normalizer)
            if cfg.agent.has_reference and not isinstance(model.policy, ReferenceTD3Policy):
                raise InvalidConfig(
                    f"{self.run_dir}: a --learner fast run of tsrl 0.2.0 (its policy keeps no reference "
                    "clone); accepted: resume it with tsrl 0.2.0"
                )
            state = checkpoint.state
            episode_steps = int(self.venv.get_attr("spec")[0].max_episode_steps)
            buffer = model.replay_buffer
            assert isinstance(buffer, FeatureHerReplayBuffer)  # tsrl's runs train on HER goal envs
            buffer.grow(buffer_capacity(cfg, episode_steps))  # a larger budget on resume
            model.buffer_size = buffer.buffer_size
            if cfg.agent.demos.active:  # the demonstrations came back in the replay buffer
                attach_bc_loss(model, cfg.agent.demos)
            attach_added_losses(model, cfg.agent)
            # The env restarts with a new episode, seeded from (seed, episodes done).
            self.venv.seed(int(np.random.SeedSequence([cfg.seed, state.episodes]).generate_state(1)[0]))
            if self.venv.has_attr("continue_from"):  # DemoResets: its curriculum goes on, not from its start
                assert checkpoint.rng is not None  # verified for training
                curriculum = checkpoint.rng.get(DEMO_RESETS)  # None in a checkpoint from before it was kept
                self.venv.env_method("continue_from", state.env_steps, state.episodes, curriculum)
        if checkpoint is not None and self.normalizer is not None and cfg.agent.fixed_normalizer:
            self.normalizer.training = False  # the statistics came back with the checkpoint: kept as saved
        last_row = truncate_progress(self.run_dir, state.clock if checkpoint else -1, _clock_column(cfg))
        model.set_logger(configure(str(self.run_dir / TENSORBOARD), ["tensorboard"]))
        update_stop = UpdateStop(model, lambda: self.stop_signal is not None)
        callback = _SafePointCallback(self, state, last_row, update_stop)
        remaining = _budget(cfg) - _clock(model)
        try:
            with StopSignals(self._note_stop):
                if remaining > 0:
                    try:
                        model.learn(remaining, callback=callback, reset_num_timesteps=False, log_interval=10)
                    except UpdateStopped:
                        callback.stopped_in_update()
                else:
                    callback.init_callback(model)
                    callback.on_training_end()
        finally:  # also on a second Ctrl-C: the progress bar ends its line, progress.csv is closed
            callback.close()
        model.logger.close()
        _summary(self.run_dir, callback)

    def _note_stop(self, signum: int) -> None:
        """A stop signal: honoured after the step in progress (module docstring)."""
        self.stop_signal = signum
        print(f"\n{signal.Signals(signum).name}: stopping after the step in progress...", file=sys.stderr)

    def close(self) -> None:
        self.evaluator.close()
        self.venv.close()


def _cut_rollout_short(model: OffPolicyAlgorithm) -> None:
    """A rollout stopped by a signal: the env step that saw it was counted but not stored, and the
    episode so far is kept as one that ended at a time limit (HER samples goals within it)."""
    model.num_timesteps -= model.n_envs
    buffer = model.replay_buffer
    assert isinstance(buffer, FeatureHerReplayBuffer)  # tsrl's runs train on HER goal envs
    with warnings.catch_warnings():  # SB3 warns that it truncates: that is the point here
        warnings.simplefilter("ignore", UserWarning)
        buffer.truncate_last_trajectory()


class _SafePointCallback(BaseCallback):
    """Evaluates, writes progress rows and checkpoints between updates; drives the progress bar."""

    def __init__(self, session: _Session, state: RunState, last_eval_step: int, update_stop: UpdateStop):
        super().__init__()
        self.session = session
        self.update_stop = update_stop
        self.in_rollout = False  # a signal stopped a rollout: its episode is cut short at the checkpoint
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

    @property
    def _model(self) -> OffPolicyAlgorithm:
        """The algorithm being trained (BaseCallback types it as any BaseAlgorithm)."""
        assert isinstance(self.model, OffPolicyAlgorithm)
        return self.model

    def wall_time(self) -> float:
        return self.wall_base + time.monotonic() - self.t0

    def _on_training_start(self) -> None:
        if self.session.progress_bar:
            from tqdm import tqdm

            self.pbar = tqdm(
                total=_budget(self.cfg),
                initial=_clock(self._model),
                unit="gradient step" if self.cfg.agent.algo == BC else "step",
                dynamic_ncols=True,
                mininterval=0.5,
                file=sys.stderr,
            )
            self._update_postfix()

    def _on_rollout_start(self) -> None:
        if self.pbar is not None and isinstance(self.model, BehaviourCloning):
            self.pbar.update(_clock(self._model) - self.pbar.n)
        self._safe_point(final=False)

    def _on_step(self) -> bool:
        if self.pbar is not None:
            self.pbar.update(self.training_env.num_envs)
            if any(self.locals.get("dones", ())):
                self._update_postfix()
        self.in_rollout = self.session.stop_signal is not None
        return not self.in_rollout  # SB3 then ends learn() without storing the step: _on_training_end

    def _on_rollout_end(self) -> None:
        self.update_stop.begin()  # an update follows

    def stopped_in_update(self) -> None:
        """After UpdateStopped: its applied gradient steps counted, a checkpoint, TrainingInterrupted."""
        self.update_stop.settle()
        self._safe_point(final=False)

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
            train_success=f"{_train_success(self._model):.2f}",
            refresh=False,
        )

    def _safe_point(self, final: bool) -> None:
        model = self._model
        step = _clock(model)
        stop = self.session.stop_signal
        if (step >= self.next_eval or final) and step != self.last_eval_step and stop is None:
            try:
                self._evaluate(model, step)
                self.next_eval = (step // self.cfg.eval_freq + 1) * self.cfg.eval_freq
            except EvaluationStopped:  # a signal during it: checkpointed below, evaluated again on resume
                stop = self.session.stop_signal
        if self.in_rollout:
            _cut_rollout_short(model)
        if step >= self.next_checkpoint or final or stop is not None:
            self.next_checkpoint = (step // self.cfg.checkpoint_freq + 1) * self.cfg.checkpoint_freq
            state = RunState(
                model.num_timesteps,
                model._episode_num,
                self.wall_time(),
                self.next_eval,
                self.next_checkpoint,
                self.eval_time,
                model._n_updates if isinstance(model, BehaviourCloning) else 0,
            )
            save_checkpoint(self.session.run_dir, model, self.session.normalizer, state)
        if stop is not None:
            model.logger.close()
            self.close()
            raise TrainingInterrupted(stop, self.session.run_dir, model.num_timesteps)

    def _evaluate(self, model: OffPolicyAlgorithm, step: int) -> None:
        t0 = time.monotonic()
        result = self.session.evaluator.evaluate(
            model, self.session.normalizer, stop=lambda: self.session.stop_signal is not None
        )
        self.eval_time += time.monotonic() - t0
        losses = model.logger.name_to_value
        row = {
            "env_steps": model.num_timesteps,
            "gradient_steps": model._n_updates,
            "episodes": model._episode_num,
            "wall_time_s": f"{self.wall_time():.3f}",
            "eval_time_s": f"{self.eval_time:.3f}",
            "eval_success_rate": f"{result.success_rate:.4f}",
            "eval_final_distance_m": f"{result.mean_final_distance:.5f}",
            "train_success_rate": _fmt(_train_success(model)),
            "critic_loss": _fmt(losses.get("train/critic_loss")),
            "actor_loss": _fmt(losses.get("train/actor_loss")),
            "eval_penalised_rate": _fmt(result.penalised_rate),
        }
        self.writer.writerow(row)
        self.progress_file.flush()
        model.logger.record("eval/success_rate", result.success_rate)
        model.logger.record("eval/final_distance_m", result.mean_final_distance)
        if math.isfinite(result.penalised_rate):
            model.logger.record("eval/penalised_rate", result.penalised_rate)
        model.logger.record("time/episodes", model._episode_num)
        model.logger.dump(step)
        self.last_eval_step = step
        self.last_success = result.success_rate
        self._update_postfix()


def _budget(cfg: TrainConfig) -> int:
    """The run's budget on its clock: env steps, or behaviour cloning's gradient steps."""
    return cfg.agent.bc_steps if cfg.agent.algo == BC else cfg.total_timesteps


def _clock(model: OffPolicyAlgorithm) -> int:
    """The run's progress on its clock (RunState.clock): env steps, or BC's gradient steps."""
    return model._n_updates if isinstance(model, BehaviourCloning) else model.num_timesteps


def _clock_column(cfg: TrainConfig) -> str:
    """The progress.csv column of the run's clock."""
    return "gradient_steps" if cfg.agent.algo == BC else "env_steps"


def _train_success(model: OffPolicyAlgorithm) -> float:
    buf = model.ep_success_buffer
    return float(np.mean(buf)) if buf else float("nan")


def _fmt(value: float | None) -> str:
    return "" if value is None or not math.isfinite(float(value)) else f"{float(value):.10g}"


def _summary(run_dir: Path, callback: _SafePointCallback) -> None:
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
