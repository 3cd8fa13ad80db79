"""Runs an experiment's grid: on local worker processes (default) or on a Ray cluster.

Local: `workers` spawned processes (default: one per available core), each with one torch thread,
each running one run at a time. A run that crashes its process (segfault, out of memory) is reported
as failed, the process replaced, and the others go on. Ray (`pip install 'tsrl[ray]'`): one task per
run with one CPU, on the cluster at `address` or on a local instance (`"local"`); the results folder
must be on a file system every node sees at the same path.

Both are backends of one scheduler (`_schedule`), which alone decides when runs start and how they
stop: Ctrl-C (or SIGTERM) stops launching runs and asks the running ones to checkpoint and stop; a
second one ends them at once.
"""

from __future__ import annotations

import contextlib
import json
import math
import multiprocessing as mp
import os
import shutil
import signal
import sys
import time
from collections import deque
from collections.abc import Iterator
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any, Protocol, TextIO

from ..agents.config import TrainConfig
from ..agents.run_folder import read_progress
from ..exceptions import InvalidConfig
from ..files import write_atomic
from ..signals import in_main_thread
from .config import (
    EXPERIMENT_FILE,
    WORKER_ENV,
    DemoRecipe,
    ExperimentConfig,
    Key,
    config_labels,
    local_workers,
)
from .runner import ERROR_FILE, RunOutcome, checkpoint_steps, config_difference, run_one, run_state


def run_experiment(
    exp: ExperimentConfig,
    out_dir: Path | str,
    workers: int | None = None,
    ray_address: str | None = None,
    stream: TextIO | None = None,
) -> list[RunOutcome]:
    """Runs every run of `exp` into `<out_dir>/<exp.name>/`; returns their outcomes in grid order.

    Finished runs are skipped without starting a worker; partial ones resume from their checkpoints.
    """
    if workers is not None and workers < 1:
        raise InvalidConfig(f"--workers must be >= 1; got {workers}")
    exp_dir = Path(out_dir) / exp.name
    runs = exp.runs(exp_dir.resolve())
    _check_run_folders(runs, exp_dir)  # before experiment.json is replaced
    exp_dir.mkdir(parents=True, exist_ok=True)
    write_atomic(exp_dir / EXPERIMENT_FILE, json.dumps(exp.to_dict(), indent=2) + "\n")

    display = Progress(runs, exp_dir, stream if stream is not None else sys.stderr)
    outcomes: dict[str, RunOutcome] = {}
    todo = []
    try:
        for cfg in runs:  # the parent checks what is done: finished runs cost no worker
            try:
                finished = run_state(cfg, exp_dir / cfg.run_name) == "finished"
            except Exception:  # noqa: BLE001  (a bad folder is the worker's to report, in error.txt)
                finished = False
            if finished:
                outcome = run_one(cfg, exp_dir)  # cheap: only reads the folder
                outcomes[cfg.run_name] = outcome
                display.finished(outcome)
            else:
                todo.append(cfg)
        if exp.demos is not None:
            record_missing_demos(exp.demos, todo, display)

        def backend(n: int) -> _Backend:
            if ray_address is not None:
                return _RayPool(exp_dir, ray_address, workers)
            return _LocalPool(exp_dir, min(local_workers(workers), n))

        first = [cfg for cfg in todo if cfg.init_from is None]
        if first:
            _schedule(first, backend(len(first)), display, outcomes)
        tuned = [cfg for cfg in todo if cfg.init_from is not None]  # [[finetune]]: after their sources
        if tuned:
            startable = _startable(tuned, outcomes, display)
            if startable:
                _schedule(startable, backend(len(startable)), display, outcomes)
    finally:
        display.close()
    return [outcomes[cfg.run_name] for cfg in runs if cfg.run_name in outcomes]


def run_configs(
    runs: list[TrainConfig], exp_dir: Path | str, workers: int | None = None, stream: TextIO | None = None
) -> list[RunOutcome]:
    """Runs `runs` (of distinct run names) into `exp_dir` on local worker processes, as
    `run_experiment` runs a grid but without a definition file (no experiment.json, demonstrations or
    fine-tuning): a finished run is reused, an interrupted one resumed; outcomes in the order of `runs`."""
    exp_dir = Path(exp_dir)
    _check_run_folders(runs, exp_dir)
    exp_dir.mkdir(parents=True, exist_ok=True)
    display = Progress(runs, exp_dir, stream if stream is not None else sys.stderr)
    outcomes: dict[str, RunOutcome] = {}
    try:
        _schedule(runs, _LocalPool(exp_dir, min(local_workers(workers), len(runs))), display, outcomes)
    finally:
        display.close()
    return [outcomes[cfg.run_name] for cfg in runs]


def _check_run_folders(runs: list[TrainConfig], exp_dir: Path) -> None:
    """Raises InvalidConfig (one line) where a run's folder holds a run of another config: a changed
    definition is refused before anything is written, experiment.json included, instead of each of its
    runs failing in turn. A damaged folder is left to its worker to report (error.txt)."""
    for cfg in runs:
        try:
            diff = config_difference(cfg, exp_dir / cfg.run_name)
        except Exception:  # noqa: BLE001  (reported by the run's worker)
            diff = ""
        if diff:
            raise InvalidConfig(
                f"experiment {exp_dir.name}: run folder {exp_dir / cfg.run_name} holds a run of another "
                f"config ({diff}); {EXPERIMENT_FILE} kept; accepted: the definition its runs were made with, "
                "or another --out-dir"
            )


def _startable(
    tuned: list[TrainConfig], outcomes: dict[str, RunOutcome], display: Progress
) -> list[TrainConfig]:
    """The fine-tuning runs whose source run has finished. After a stop (an interrupted run) none
    starts ("not started"); one whose source did not finish is failed, its source named."""
    stopped = any(o.status == "interrupted" for o in outcomes.values())
    startable = []
    for cfg in tuned:
        source = Path(cfg.init_from or "")
        if stopped:
            outcome = RunOutcome(cfg.run_name, "interrupted", 0, 0.0, error="not started")
        elif checkpoint_steps(source) >= cfg.total_timesteps:  # the source reached the same budget
            startable.append(cfg)
            continue
        else:
            outcome = RunOutcome(
                cfg.run_name, "failed", 0, 0.0, error=f"its source run {source.name} has not finished"
            )
        outcomes[cfg.run_name] = outcome
        display.finished(outcome)
    return startable


def record_missing_demos(recipe: DemoRecipe, todo: list[TrainConfig], display: Progress) -> None:
    """Records the demonstration file of each configuration in `todo` that has none yet (written whole,
    then renamed: an interrupted recording leaves no file)."""
    from ..agents.demo_files import save_demos, summary_line
    from ..agents.demonstrators import record_demos

    for cfg in todo:
        path = Path(cfg.agent.demos.path or "")
        if not cfg.agent.demos.active or path.is_file():  # off: the run never reads the file
            continue
        display.message(f"recording {recipe.episodes} demonstrations for {cfg.env_name}")
        demos = record_demos(cfg.env_id, recipe.episodes, obs=cfg.obs, action=cfg.action, seed=recipe.seed)
        if demos.n_episodes < recipe.episodes:
            raise InvalidConfig(
                f"[demos]: the scripted demonstrator of {cfg.env_name} succeeded on only {demos.n_episodes} "
                f"of {demos.meta['attempted']} episodes; {recipe.episodes} needed"
            )
        display.message(summary_line(demos, save_demos(demos, path)))


# -- the one scheduler and its stop logic --------------------------------------------------------------
class ExperimentStopped(KeyboardInterrupt):
    """SIGINT or SIGTERM (`signum`) in the parent, handled as Ctrl-C; `tsrl experiment` exits 128 + signum."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _Backend(Protocol):
    """Where runs execute (local worker processes or Ray tasks). It starts, waits for, asks to stop and
    kills runs; what starts when, and when to stop, is `_schedule`'s alone."""

    def free(self) -> bool:
        """Whether a run can start now."""

    def start(self, cfg: TrainConfig) -> None:
        """Starts the run of `cfg`."""

    def running(self) -> list[TrainConfig]:
        """The runs started and not yet reported."""

    def wait(self, timeout: float, stopping: bool) -> list[RunOutcome]:
        """The outcomes of the runs that end within `timeout` seconds (`stopping`: a stop was asked
        for, so a run that ends without reporting was stopped, not failed)."""

    def release_idle(self) -> None:
        """Releases what has no run after the starts (local: idle workers exit)."""

    def stop(self) -> None:
        """Asks every running run to save a checkpoint and stop."""

    def kill(self) -> None:
        """Ends every running run at once, without a checkpoint."""

    def close(self) -> None:
        """Releases the backend (after the last outcome, or on the way out of an error)."""


@contextlib.contextmanager
def stop_signals() -> Iterator[None]:
    """SIGINT and SIGTERM raise ExperimentStopped in the main thread for the block. SIGINT too where the
    process inherited it ignored (a shell's background job), as `tsrl train` installs its own handler."""

    def on_signal(signum: int, frame: object) -> None:
        raise ExperimentStopped(signum)

    signals = (signal.SIGINT, signal.SIGTERM) if in_main_thread() else ()
    previous = {sig: signal.signal(sig, on_signal) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """SIGINT and SIGTERM that arrive during the block are raised again after it (the first of them),
    so that a signal never cuts a worker's start in half: a half-sent pipe makes the new process die
    with a traceback of its own."""
    if not in_main_thread():
        yield
        return
    caught: list[int] = []
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {sig: signal.signal(sig, lambda signum, frame: caught.append(signum)) for sig in signals}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if caught:
            signal.raise_signal(caught[0])


def _schedule(
    todo: list[TrainConfig], backend: _Backend, display: Progress, outcomes: dict[str, RunOutcome]
) -> None:
    """Runs `todo` on `backend`, a run whenever it has room, and stops the same way on both backends:

    - the first Ctrl-C (or SIGTERM) starts no new run and asks the running ones to save a checkpoint
      and stop; the loop then collects their outcomes ("interrupted", resumable);
    - a run that ends interrupted (its worker was signalled directly) also starts no new run;
    - a second Ctrl-C (or SIGTERM) kills the running runs and raises KeyboardInterrupt;
    - a failed run stops nothing: the others go on.

    Runs that never started are reported interrupted ("not started"); after a stop by a signal,
    ExperimentStopped is raised once every outcome is in.
    """
    pending = deque(todo)
    stopping = False
    stopped_by: int | None = None
    with stop_signals():
        try:
            while True:
                try:
                    while pending and not stopping and backend.free():
                        cfg = pending.popleft()
                        backend.start(cfg)
                        display.started(cfg)
                    backend.release_idle()
                    if not backend.running():
                        break
                    for outcome in backend.wait(display.refresh_s, stopping):
                        outcomes[outcome.run_name] = outcome
                        display.finished(outcome)
                        if outcome.status == "interrupted" and not stopping:
                            stopping = True
                            display.message("a run was interrupted: no new runs start")
                    display.refresh(backend.running())
                except KeyboardInterrupt as err:
                    signum = err.signum if isinstance(err, ExperimentStopped) else signal.SIGINT
                    if stopping:
                        backend.kill()
                        raise ExperimentStopped(signum) from None
                    stopping, stopped_by = True, signum
                    display.message(
                        f"stopping: {len(backend.running())} running run(s) save a checkpoint and stop; "
                        f"{len(pending)} not started; Ctrl-C again to stop at once"
                    )
                    backend.stop()
        finally:
            backend.close()
    for cfg in pending:
        outcomes[cfg.run_name] = RunOutcome(cfg.run_name, "interrupted", 0, 0.0, error="not started")
    if stopped_by is not None:
        raise ExperimentStopped(stopped_by)


# -- local process pool ----------------------------------------------------------------------------
def _worker(conn: Connection) -> None:
    """A spawned worker process: runs the (config, experiment dir) it receives until it gets None."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # training handles SIGINT itself while it runs
    while (task := conn.recv()) is not None:
        conn.send(run_one(*task))


class _Worker:
    """A worker process, its end of the pipe, and the run it is on (None: idle)."""

    def __init__(self, ctx: mp.context.SpawnContext):
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child,), daemon=True)
        saved = {k: os.environ.get(k) for k in WORKER_ENV}
        os.environ.update(WORKER_ENV)  # inherited by the child before it imports torch
        try:
            self.proc.start()
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k)
                else:
                    os.environ[k] = v
        child.close()
        self.cfg: TrainConfig | None = None
        self.t0 = 0.0

    def give(self, cfg: TrainConfig, exp_dir: Path) -> None:
        self.conn.send((cfg, str(exp_dir)))
        self.cfg, self.t0 = cfg, time.monotonic()


class _LocalPool:
    """Up to `size` persistent worker processes (torch's import costs seconds), one run at a time
    each; a worker that dies is reported with its run and replaced at the next start."""

    def __init__(self, exp_dir: Path, size: int):
        self.exp_dir, self.size = exp_dir, size
        self.ctx = mp.get_context("spawn")
        self.workers: list[_Worker] = []

    def free(self) -> bool:
        return len(self.running()) < self.size

    def start(self, cfg: TrainConfig) -> None:
        with _signals_deferred():
            idle = [w for w in self.workers if w.cfg is None]
            worker = idle[0] if idle else _Worker(self.ctx)
            if not idle:
                self.workers.append(worker)
            worker.give(cfg, self.exp_dir)

    def running(self) -> list[TrainConfig]:
        return [w.cfg for w in self.workers if w.cfg is not None]

    def wait(self, timeout: float, stopping: bool) -> list[RunOutcome]:
        busy = [w for w in self.workers if w.cfg is not None]
        ready = set(wait([w.conn for w in busy] + [w.proc.sentinel for w in busy], timeout))
        out = []
        for w in busy:
            if w.conn in ready or w.proc.sentinel in ready:
                out.append(_collect(w, self.exp_dir, stopping))
                w.cfg = None
                if not w.proc.is_alive():
                    self.workers.remove(w)
        return out

    def release_idle(self) -> None:
        for w in [w for w in self.workers if w.cfg is None]:
            w.conn.send(None)  # nothing left for it
            w.conn.close()
            self.workers.remove(w)

    def stop(self) -> None:
        for w in self.workers:
            if w.cfg is not None and w.proc.pid is not None:
                os.kill(w.proc.pid, signal.SIGTERM)  # training saves a checkpoint and stops

    def kill(self) -> None:
        for w in self.workers:
            w.proc.kill()
        for w in self.workers:
            w.proc.join()  # gone when this returns: no run outlives the pool

    def close(self) -> None:
        self.kill()  # none is left after the last outcome; on an error none outlives the pool
        self.workers.clear()


def _collect(w: _Worker, exp_dir: Path, stopping: bool) -> RunOutcome:
    """The outcome the worker sent, or one that says how its process died."""
    assert w.cfg is not None  # only busy workers report
    try:
        if w.conn.poll():
            return w.conn.recv()
    except (EOFError, OSError):
        pass
    w.proc.join()
    w.conn.close()
    code = w.proc.exitcode
    how = f"signal {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit code {code}"
    name, seconds = w.cfg.run_name, time.monotonic() - w.t0
    if stopping:
        return RunOutcome(name, "interrupted", 0, seconds, error=f"worker stopped ({how})")
    likely = "; out of memory?" if code == -signal.SIGKILL else ""
    error = f"worker process died ({how}{likely}) before reporting"
    (exp_dir / name).mkdir(parents=True, exist_ok=True)
    (exp_dir / name / ERROR_FILE).write_text(error + "\n")
    return RunOutcome(name, "failed", 0, seconds, error=error)


# -- Ray -------------------------------------------------------------------------------------------
def _ray_run(cfg: TrainConfig, exp_dir: str) -> RunOutcome:
    """Body of a Ray task: one run (Ray sets OMP_NUM_THREADS to the task's 1 CPU)."""
    return run_one(cfg, exp_dir)


class _RayPool:
    """One Ray task (one CPU) per run, at most `workers` (default: the cluster's CPUs) at a time, on
    the cluster at `address` or a local instance ("local"), which is shut down on close."""

    def __init__(self, exp_dir: Path, address: str, workers: int | None):
        try:
            import ray
        except ImportError:
            raise InvalidConfig("--ray needs Ray: pip install 'tsrl[ray]'") from None
        self.ray = ray
        self.started_here = not ray.is_initialized()
        if self.started_here:
            try:
                if address == "local":
                    ray.init(address="local", include_dashboard=False, num_cpus=workers, log_to_driver=False)
                else:
                    ray.init(address=address, log_to_driver=False)
            except (ConnectionError, ValueError, RuntimeError) as err:
                raise InvalidConfig(f"cannot connect to Ray at {address!r}: {err}".splitlines()[0]) from None
        self.exp_dir = exp_dir
        self.slots = workers or max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.task = ray.remote(num_cpus=1, max_retries=0)(_ray_run)
        self.refs: dict[Any, tuple[TrainConfig, float]] = {}

    def free(self) -> bool:
        return len(self.refs) < self.slots

    def start(self, cfg: TrainConfig) -> None:
        self.refs[self.task.remote(cfg, str(self.exp_dir.resolve()))] = (cfg, time.monotonic())

    def running(self) -> list[TrainConfig]:
        return [cfg for cfg, _ in self.refs.values()]

    def wait(self, timeout: float, stopping: bool) -> list[RunOutcome]:
        ray = self.ray
        done, _ = ray.wait(list(self.refs), num_returns=1, timeout=timeout)
        out = []
        for ref in done:
            cfg, t0 = self.refs.pop(ref)
            try:
                out.append(ray.get(ref))
            except ray.exceptions.TaskCancelledError:
                out.append(
                    RunOutcome(cfg.run_name, "interrupted", 0, time.monotonic() - t0, error="cancelled")
                )
            except ray.exceptions.RayError as err:
                error = f"Ray task failed: {err}".splitlines()[0]
                (self.exp_dir / cfg.run_name).mkdir(parents=True, exist_ok=True)
                (self.exp_dir / cfg.run_name / ERROR_FILE).write_text(str(err) + "\n")
                out.append(RunOutcome(cfg.run_name, "failed", 0, time.monotonic() - t0, error=error))
        return out

    def release_idle(self) -> None:
        pass  # Ray's workers are Ray's

    def stop(self) -> None:
        for ref in self.refs:
            self.ray.cancel(ref)  # KeyboardInterrupt in the task: training checkpoints and stops

    def kill(self) -> None:
        for ref in self.refs:
            self.ray.cancel(ref, force=True)

    def close(self) -> None:
        if self.started_here:
            self.ray.shutdown()


# -- progress display ------------------------------------------------------------------------------
class Progress:
    """Runs done, running and left: a line per finished run, and on a terminal a status line with the
    running runs' env steps, rewritten in place."""

    refresh_s = 2.0

    def __init__(self, runs: list[TrainConfig], exp_dir: Path, stream: TextIO):
        self.total = len(runs)
        keys: list[Key] = [(c.env_id, c.obs, c.action, c.agent.algo, "") for c in runs]
        self.labels = {c.run_name: f"{k} s{c.seed}" for c, k in zip(runs, config_labels(keys), strict=True)}
        self.exp_dir = exp_dir
        self.stream = stream
        self.tty = stream.isatty()
        self.counts = {"trained": 0, "resumed": 0, "skipped": 0, "failed": 0, "interrupted": 0}
        self.running: list[TrainConfig] = []
        self.message(f"experiment {exp_dir.name}: {self.total} runs -> {exp_dir}")

    @property
    def done(self) -> int:
        return sum(self.counts.values())

    def started(self, cfg: TrainConfig) -> None:
        self.running.append(cfg)
        if self.tty:
            self._status()
        else:
            self.message(f"started {cfg.run_name} | {self._counts()}")

    def finished(self, outcome: RunOutcome) -> None:
        self.counts[outcome.status] += 1
        self.running = [c for c in self.running if c.run_name != outcome.run_name]
        detail = f"{outcome.env_steps} env steps"
        if not math.isnan(outcome.success):
            detail += f", eval success {outcome.success:.2f}"
        if outcome.status != "skipped":
            detail += f", {outcome.seconds:.0f} s"
        if outcome.error:
            detail += f" -- {outcome.error}"
        width = len(str(self.total))
        line = f"[{self.done:>{width}}/{self.total}] {outcome.status:<11} {outcome.run_name}: {detail}"
        self.message(line if self.tty else f"{line} | {self._counts()}")

    def refresh(self, running: list[TrainConfig]) -> None:
        self.running = list(running)
        self._status(with_steps=True)

    def message(self, text: str) -> None:
        with _signals_deferred():  # a stop's handler raises: not between the text and its newline
            self._clear()
            print(text, file=self.stream, flush=True)

    def close(self) -> None:
        self._clear()
        c = self.counts
        not_started = f", {self.total - self.done} not started" if self.done < self.total else ""
        self.message(
            f"{self.done}/{self.total} runs: {c['trained']} trained, {c['resumed']} resumed, "
            f"{c['skipped']} skipped (finished before), {c['failed']} failed, {c['interrupted']} interrupted"
            + not_started
        )

    def _counts(self) -> str:
        left = self.total - self.done - len(self.running)
        failed = f", {self.counts['failed']} failed" if self.counts["failed"] else ""
        return f"done {self.done}/{self.total}{failed} | running {len(self.running)} | left {left}"

    def _status(self, with_steps: bool = False) -> None:
        if not self.tty:
            return
        text = self._counts()
        if with_steps and self.running:
            steps = []
            for cfg in self.running:
                rows = read_progress(self.exp_dir / cfg.run_name)
                at = int(rows[-1]["env_steps"]) if rows else 0
                steps.append(f"{self.labels[cfg.run_name]}: {at}/{cfg.total_timesteps}")
            text += " | " + ", ".join(steps)
        self.stream.write("\r\033[K" + text[: shutil.get_terminal_size().columns - 1])
        self.stream.flush()

    def _clear(self) -> None:
        if self.tty:
            self.stream.write("\r\033[K")
