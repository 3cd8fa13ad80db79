"""The deploy loop (episodes of a Controller on a RobotBackend), its log, and the replay of a log.

One episode: the backend's reset, the goal; then per control period one policy step (`act` on a
fresh state) and `control_period / backend.period` servo ticks, each sending `interpolate(t + h)`
(the position the servos are to reach at the tick's end) and waiting for the next tick. After the
last step the state is read once more and the episode's success is the task's rule on it.

The log is JSON lines: a header (export folder, contract sha256, backend, options), one record per
policy step (state, features, action, IK target, joint target, the period's servo commands and those
the robot refused, faults, compute time, wall-clock start and latency) and one per episode (success,
why the safety layer stopped, if it did; the loop's figures: tsrl.deploy.timing). A command the robot
refuses is a fault the safety layer handles (hold, count, stop after several in a row: `run_episodes`). `replay` recomputes every step from its logged inputs with a fresh controller
(the commands must come out the same) and renders the logged states.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from ..exceptions import InvalidConfig
from .backends import MujocoBackend, RobotBackend, check_backend
from .contract import CONTRACT, sha256
from .controller import Controller, ControllerOptions, Cycle
from .safety import COMMAND_REFUSED, MAX_REFUSED_IN_ROW, RefusedCommands
from .timing import LoopTiming

#: How the servo commands of a period are made: the limiter's interpolation (always on hardware), or
#: the policy step's target held for the period as the training environment does (MuJoCo only).
ServoMode = Literal["interpolate", "hold"]


@dataclass
class EpisodeResult:
    """One deployed episode."""

    seed: int | None
    success: bool
    """The task's success rule on the last measured state (the controller's features)."""
    true_success: bool | None
    """The same on the simulator's true state (MuJoCo backend), else None."""
    distance: float
    steps: int
    faults: Counter[str] = field(default_factory=Counter)
    compute_s: list[float] = field(default_factory=list)
    """Controller compute time of each policy step (act) [s], wall clock."""
    interpolate_s: list[float] = field(default_factory=list)
    """Time of each `interpolate` call [s], wall clock."""
    start_s: list[float] = field(default_factory=list)
    """Wall-clock start of each policy step [s, time.perf_counter] (tsrl.deploy.timing)."""
    latency_s: list[float] = field(default_factory=list)
    """Each policy step's latency [s]: its start to the period's first command sent."""
    timing: LoopTiming | None = None
    """The episode's control-loop figures (rate, latency, jitter), set at its end."""
    stopped: str | None = None
    """Why the safety layer stopped the deployment in this episode (one line), or None."""


class DeployLog:
    """A JSON-lines log of a deployment (module docstring); `None`-safe helpers for the loop."""

    def __init__(self, path: Path | str, header: dict[str, Any]):
        self.path = Path(path)
        self._header = {"type": "header", **header}
        # Opened with the first episode's start (a backend that never connects leaves no file), then
        # open across the episodes, flushed after every record (a crash keeps what was logged); close().
        self._file: IO[str] | None = None

    def start(self, episode: int, seed: int | None, t: float, q: np.ndarray, goal: np.ndarray) -> None:
        """An episode's start: the controller's reset at time t from joint positions q with the goal."""
        self._write({"type": "start", "episode": episode, "seed": seed, "t": t, "q": q, "goal": goal})

    def cycle(
        self,
        episode: int,
        step: int,
        cycle: Cycle,
        servo_t: list[float],
        servo: list[np.ndarray],
        compute_s: float,
        wall_t: float,
        latency_s: float,
        refused: Sequence[tuple[int, str]] = (),
    ) -> None:
        """A policy step: the Cycle, then the period's servo calls (times [s] and commands) and those
        the robot refused ([tick, why], the commands holding after each); its wall-clock start [s since
        the episode's first step] and latency [s]."""
        record = {"type": "cycle", "episode": episode, "step": step, "compute_s": compute_s}
        record |= {"wall_t": wall_t, "latency_s": latency_s}
        record |= dataclasses.asdict(cycle)
        record |= {"servo_t": servo_t, "servo": servo, "refused": [list(r) for r in refused]}
        self._write(record)

    def episode(self, index: int, result: EpisodeResult) -> None:
        self._write(
            {
                "type": "episode",
                "episode": index,
                "seed": result.seed,
                "success": result.success,
                "true_success": result.true_success,
                "distance": result.distance,
                "steps": result.steps,
                "faults": dict(result.faults),
                "stopped": result.stopped,
                "timing": None if result.timing is None else result.timing.record(),
            }
        )

    def close(self) -> None:
        if self._file is not None:
            self._file.close()

    def _write(self, record: dict[str, Any]) -> None:
        if self._file is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "w")  # noqa: SIM115
            self._file.write(json.dumps(self._header, default=_jsonable) + "\n")
        self._file.write(json.dumps(record, default=_jsonable) + "\n")
        self._file.flush()


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


@dataclass(frozen=True)
class LogRecords:
    """A deploy log's complete records, and whether (and where) the log ends early."""

    header: dict[str, Any]
    cycles: list[dict[str, Any]]
    """The start and cycle records, in order."""
    episodes: list[dict[str, Any]]
    ends_early: str | None
    """None for a whole log; else what is missing (a cut last line, an episode without its end)."""


def read_log(path: Path | str) -> tuple[dict[str, Any], list[dict[str, Any]], list[dict[str, Any]]]:
    """(header, start and cycle records in order, episode records) of a deploy log (`read_log_records`)."""
    records = read_log_records(path)
    return records.header, records.cycles, records.episodes


def read_log_records(path: Path | str) -> LogRecords:
    """A deploy log's complete records. A log cut anywhere (as by a crash: a last line cut short, an
    episode without its end record) gives its complete records and says where it ends early; a line
    that is not JSON before the last is InvalidConfig naming the file and the line's number."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as err:
        raise InvalidConfig(f"{path}: not a readable deploy log ({err})") from None
    lines = text.split("\n")
    last = max((i for i, line in enumerate(lines) if line.strip()), default=-1)
    records: list[dict[str, Any]] = []
    ends_early = None
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError as err:
            if i != last:
                raise InvalidConfig(f"{path}: line {i + 1} is not a JSON record ({err.msg})") from None
            ends_early = f"its last line ({i + 1}) is cut short"
    if not records or records[0].get("type") != "header":
        raise InvalidConfig(f"{path}: not a deploy log (no header line); write one with `tsrl deploy`")
    cycles = [r for r in records if r.get("type") in ("start", "cycle")]
    episodes = [r for r in records if r.get("type") == "episode"]
    started = sum(r.get("type") == "start" for r in cycles)
    if started > len(episodes):
        cut = f"episode {started - 1} has no end record"
        ends_early = cut if ends_early is None else f"{ends_early}; {cut}"
    return LogRecords(records[0], cycles, episodes, ends_early)


def run_episodes(
    controller: Controller,
    backend: RobotBackend,
    seeds: Sequence[int | None],
    goals: Sequence[ArrayLike | None] | None = None,
    log: DeployLog | None = None,
    servo: ServoMode = "interpolate",
    max_refused: int = MAX_REFUSED_IN_ROW,
    stop: Callable[[], str | None] = lambda: None,
) -> list[EpisodeResult]:
    """Runs one episode per seed (goals[i], or drawn as the task draws it with seeds[i]); see the
    module docstring. For a dry run, pass a ShadowBackend (nothing is sent; logged alike).

    A servo command the backend refuses (`send` says why) is a fault the safety layer handles
    (tsrl.deploy.safety.RefusedCommands): the step reports COMMAND_REFUSED, the commands hold until
    the next policy step; `max_refused` in a row stop the deployment there (`EpisodeResult.stopped`
    says why; no further episode runs; the backend is closed, which stops the arm). `stop()` is asked
    after every servo tick: a reason (an operator's signal) stops the deployment there alike."""
    check_backend(backend, controller.contract)
    if servo == "hold" and not isinstance(backend, MujocoBackend):
        raise InvalidConfig("--servo hold (the training env's command timing) is for the MuJoCo backend only")
    ticks = round(controller.control_period / backend.period)
    if ticks < 1 or not math.isclose(ticks * backend.period, controller.control_period):
        raise InvalidConfig(
            f"the control period {controller.control_period} s is not a multiple of the backend's servo "
            f"period {backend.period} s"
        )
    results = []
    refusals = RefusedCommands(max_refused)
    backend.connect()
    try:
        for i, seed in enumerate(seeds):
            goal = goals[i] if goals is not None and goals[i] is not None else None
            if goal is None:
                if seed is None:
                    raise InvalidConfig("an episode needs a goal or a seed to draw one from")
                goal = controller.sample_goal(seed)
            result = _episode(
                controller, backend, i, seed, np.asarray(goal, np.float64), ticks, log, servo, refusals, stop
            )
            results.append(result)
            if log is not None:
                log.episode(i, result)
            if result.stopped is not None:
                break
    finally:
        backend.close()
    return results


def _episode(
    controller: Controller,
    backend: RobotBackend,
    index: int,
    seed: int | None,
    goal: np.ndarray,
    ticks: int,
    log: DeployLog | None,
    servo: ServoMode,
    refusals: RefusedCommands,
    stop: Callable[[], str | None],
) -> EpisodeResult:
    backend.reset(seed)
    if isinstance(backend, MujocoBackend):
        backend.place_goal_marker(goal)
    state = backend.read_state()
    controller.reset(state.q, backend.now(), goal)
    if log is not None:
        log.start(index, seed, backend.now(), state.q, goal)
    steps = controller.contract.task.episode_steps
    result = EpisodeResult(seed, False, None, math.nan, steps)
    h = backend.period
    for step in range(steps):
        result.start_s.append(time.perf_counter())
        state = backend.read_state()
        t = backend.now()
        start = time.perf_counter()
        q_target = controller.act(state.q, state.qd, state.objects, t=t, stamp=state.time, tool=state.tool)
        result.compute_s.append(time.perf_counter() - start)
        cycle = controller.last
        assert cycle is not None
        result.faults.update(cycle.faults)
        times, commands = [], []
        refused: list[tuple[int, str]] = []
        for tick in range(ticks):
            t_servo = backend.now() + h  # the command is where the servos are to be at the tick's end
            start = time.perf_counter()
            command = controller.interpolate(t_servo)
            result.interpolate_s.append(time.perf_counter() - start)
            if servo == "hold":
                command = q_target
            times.append(t_servo)
            commands.append(command)
            why = backend.send(command, controller.tool)
            if tick == 0:
                result.latency_s.append(time.perf_counter() - result.start_s[-1])
            if why is None:
                refusals.accepted()
            else:  # the safety layer's rule: hold, count, stop after max_refused in a row
                controller.refused(t_servo)
                refused.append((tick, why))
                result.faults[COMMAND_REFUSED] += 1
                result.stopped = refusals.refused(why)
                if result.stopped is not None:
                    break
            backend.wait()
            result.stopped = stop()
            if result.stopped is not None:
                break
        if log is not None:
            wall_t = result.start_s[-1] - result.start_s[0]
            log.cycle(
                index,
                step,
                cycle,
                times,
                commands,
                result.compute_s[-1],
                wall_t,
                result.latency_s[-1],
                refused,
            )
        if result.stopped is not None:
            break
    result.timing = LoopTiming.of(result.start_s, result.latency_s, controller.control_period)
    state = backend.read_state()
    info = controller.outcome(state.q, state.qd, state.objects, state.tool)
    result.success = bool(info.get("is_success", False))
    result.distance = float(info.get("distance", math.nan))
    if isinstance(backend, MujocoBackend):
        result.true_success = bool(backend.outcome()["is_success"])
    return result


def log_header(
    export_dir: Path, backend: RobotBackend, options: ControllerOptions, extra: dict[str, Any]
) -> dict[str, Any]:
    """The header of a deploy log: what a replay needs to rebuild the controller."""
    return {
        "export_dir": str(Path(export_dir).resolve()),
        "contract_sha256": sha256(Path(export_dir) / CONTRACT),
        "backend": backend.name,
        "servo_period_s": backend.period,
        "options": dataclasses.asdict(options),
        **extra,
    }


@dataclass(frozen=True)
class ReplayResult:
    """How a replay compared with its log."""

    cycles: int
    max_target_difference: float
    """Largest |recomputed - logged| joint target over all steps [rad]."""
    max_action_difference: float
    max_servo_difference: float
    """Largest |recomputed - logged| servo command [rad] (0 for a log of --servo hold)."""
    video: Path | None
    ends_early: str | None = None
    """None for a whole log; else where it ends early (`LogRecords.ends_early`)."""


def replay(
    log_path: Path | str, video: Path | None = None, size: tuple[int, int] = (320, 320), every: int = 1
) -> ReplayResult:
    """Recomputes every logged policy step and servo command with a fresh controller of the logged
    export and options (resets and servo ticks at their logged times), and renders the logged states
    into `video` (a frame every `every` policy steps)."""
    records = read_log_records(log_path)
    header, cycles = records.header, records.cycles
    folder = Path(header["export_dir"])
    if sha256(folder / CONTRACT) != header["contract_sha256"]:
        raise InvalidConfig(f"{log_path}: the export folder {folder} has changed since the log was written")
    controller = Controller.from_export(folder, ControllerOptions(**header["options"]))
    max_target = max_action = max_servo = 0.0
    n = 0
    for record in cycles:
        if record["type"] == "start":
            controller.reset(record["q"], record["t"], record["goal"])
            continue
        n += 1
        q_target = controller.act(
            record["q"],
            record["qd"],
            record["objects"],
            record["goal"],
            t=record["t"],
            stamp=record["stamp"],
            tool=record.get("tool_width"),
        )
        max_target = max(max_target, _difference(q_target, record["q_target"]))
        cycle = controller.last
        if cycle is not None and cycle.action is not None and record["action"] is not None:
            max_action = max(max_action, _difference(cycle.action, record["action"]))
        refused = {int(r[0]) for r in record.get("refused", ())}
        for tick, (t_servo, logged) in enumerate(zip(record["servo_t"], record["servo"])):
            command = controller.interpolate(t_servo)
            if header.get("servo") != "hold":
                max_servo = max(max_servo, _difference(command, logged))
            if tick in refused:
                controller.refused(t_servo)  # as the safety layer held after it
    frames = [r for r in cycles if r["type"] == "cycle"][::every]
    out = _render(controller, frames, video, size, every) if video is not None else None
    return ReplayResult(n, max_target, max_action, max_servo, out, records.ends_early)


def _difference(a: Any, b: Any) -> float:
    """max |a - b| of two arrays; NaN where either has one (a held step's action may be NaN)."""
    d = np.abs(np.asarray(a, dtype=np.float64) - np.asarray(b, dtype=np.float64))
    return (
        float(np.max(d))
        if np.isfinite(d).all()
        else (0.0 if np.array_equal(a, b, equal_nan=True) else math.nan)
    )


def _render(
    controller: Controller, cycles: list[dict[str, Any]], video: Path, size: tuple[int, int], every: int
) -> Path:
    """A frame per given policy step: the logged joint positions, objects and goal, in the exported scene."""
    import mujoco

    from ..agents.evaluation import write_video
    from ..rendering import SceneRenderer

    model = controller.model
    data = mujoco.MjData(model)
    controller.interface.bound_robot.reset_to_home(model, data)
    frames = []
    with SceneRenderer(model, *size) as renderer:
        for frame_data in _states(controller, cycles, data):
            frames.append(renderer.render(frame_data))
    return write_video(frames, video, max(1, round(1 / (every * controller.control_period))))


def _states(controller: Controller, cycles: list[dict[str, Any]], data: Any) -> Iterator[Any]:
    import mujoco

    model = controller.model
    for record in cycles:
        q = np.asarray(record["q"], dtype=np.float64)
        if not np.isfinite(q).all():
            continue  # a faulty reading the controller held through: nothing to show
        data.qpos[controller._qpos] = q
        for body, (qadr, _) in controller._objects.items():
            pose = record["objects"].get(body)
            if pose is not None and np.isfinite(pose).all():
                data.qpos[qadr : qadr + 7] = pose[:7]
        controller.interface.goal.place(data, np.asarray(record["goal"], dtype=np.float64))
        mujoco.mj_kinematics(model, data)
        yield data
