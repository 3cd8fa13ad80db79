"""`tsrl export` and `tsrl deploy`: the deployment path's commands (tsrl.cli adds DEPLOY_COMMANDS).

Commands are tyro dataclasses (fields are options, run() the work), as in tsrl.cli. Bad input raises
TsrlError, which tsrl.cli turns into one line on stderr and exit code 2. Nothing heavy is imported
until a command runs (export loads torch; deploy does not).
"""

from __future__ import annotations

import signal
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from tyro.conf import Positional, arg

from ..exceptions import InvalidConfig
from ..signals import StopSignals


@dataclass(frozen=True)
class Export:
    """Export a run's policy for deployment: policy.onnx, contract.json and copies of its files."""

    run_dir: Positional[Annotated[Path, arg(metavar="RUN_DIR")]]
    """A run folder written by `tsrl train` (its newest usable checkpoint is exported)."""
    out: Path
    """The export folder to write (replaced whole)."""
    max_joint_speed: tuple[float, ...] | None = None
    """Joint speed limits [rad/s]: one value or one per joint (default: the built-in robot's)."""
    max_joint_acceleration: tuple[float, ...] | None = None
    """Joint acceleration limits [rad/s^2]: one value or one per joint (default: the built-in robot's)."""

    def run(self) -> int:
        from ..agents.run_folder import load_config

        load_config(self.run_dir)  # a clear error before torch loads
        from .export import export_run

        out = export_run(self.run_dir, self.out, self.max_joint_speed, self.max_joint_acceleration)
        print(
            f"wrote {out} (policy.onnx, contract.json, task, robot and model files); check it with docs/deploy.md"
        )
        return 0


@dataclass(frozen=True)
class Deploy:
    """Run an exported policy on a robot (or the MuJoCo stand-in) behind the safety layer, or replay a log."""

    export_dir: Positional[Annotated[Path | None, arg(metavar="EXPORT_DIR")]] = None
    """An export folder written by `tsrl export`."""
    backend: Literal["mujoco", "ur", "franka"] = "mujoco"
    """mujoco: a simulated arm (the export's scene); ur: ur-rtde servoJ; franka: franky-control."""
    address: str | None = None
    """The robot's IP address (ur, franka)."""
    franka_realtime: bool = True
    """franka: require a realtime kernel, as libfranka does by default; --no-franka-realtime for a
    simulator of the arm (franky-sim) on an ordinary kernel."""
    episodes: int = 3
    """Episodes to run."""
    seeds: tuple[int, ...] | None = None
    """Episode seeds (the goals drawn as the task draws them; `tsrl evaluate`'s seeds give its goals);
    default: 0, 1, ..., episodes - 1."""
    goal: str | None = None
    """One goal for every episode, comma-separated in the world frame, e.g. -0.5,-0.1,0.3 [m]."""
    dry_run: bool = False
    """Shadow mode: read the robot's state, compute and log every command, send none."""
    speed_scale: float = 1.0
    """Scales the contract's joint speed and acceleration limits, in (0, 1] (0.25 for a first slow run)."""
    action_filter: float = 0.0
    """Time constant [s] of a first-order filter on the policy's action; 0: none."""
    ramp: bool = False
    """Servo commands ramp to each policy target over the control period (smoother, up to a period late)."""
    servo: Literal["interpolate", "hold"] = "interpolate"
    """interpolate: servo commands from the limiter; hold: the policy target held for the period as in
    training (mujoco only; it does not honour the speed and acceleration limits between ticks)."""
    scene: Path | None = None
    """mujoco: another model file of the same arm to simulate (default: the export's scene)."""
    realtime: bool = False
    """mujoco: pace the simulation to the wall clock (default: as fast as possible)."""
    latency: float = 0.0
    """mujoco: command latency [s]."""
    joint_noise: float = 0.0
    """mujoco: standard deviation of measured joint positions' noise [rad]."""
    object_noise: float = 0.0
    """mujoco: standard deviation of measured object positions' noise [m]."""
    drop_rate: float = 0.0
    """mujoco: probability of a lost command and of a repeated (stale) state."""
    log: Path = Path("deploy.jsonl")
    """The log of every policy step (state, features, action, targets, servo commands, timing)."""
    replay: Annotated[Path | None, arg(metavar="LOG")] = None
    """Replay this log instead: recompute every command from its logged state and render the states."""
    video: Path = Path("replay.mp4")
    """--replay: the video of the logged states."""
    video_every: int = 1
    """--replay: a frame every this many policy steps (off-screen rendering is slow on a CPU)."""

    def __post_init__(self) -> None:
        if self.video_every < 1:
            raise InvalidConfig(f"--video-every must be >= 1; got {self.video_every}")
        if self.episodes < 1:
            raise InvalidConfig(f"--episodes must be >= 1; got {self.episodes}")
        if self.replay is None and self.export_dir is None:
            raise InvalidConfig("tsrl deploy needs EXPORT_DIR (an export folder), or --replay LOG")
        if self.seeds is not None and len(self.seeds) != self.episodes:
            raise InvalidConfig(f"--seeds has {len(self.seeds)} seeds for --episodes {self.episodes}")

    def run(self) -> int:
        if self.replay is not None:
            return self._replay()
        import numpy as np

        from .backends import ShadowBackend, check_backend, make_backend
        from .controller import Controller, ControllerOptions
        from .loop import DeployLog, log_header, run_episodes
        from .timing import worst_of

        assert self.export_dir is not None
        goal = _parse_goal(self.goal)
        check_log_path(self.log)  # before anything connects
        sim = {
            "scene": self.scene,
            "realtime": self.realtime,
            "latency": self.latency,
            "joint_noise": self.joint_noise,
            "object_noise": self.object_noise,
            "drop_rate": self.drop_rate,
        }
        if self.backend != "franka" and not self.franka_realtime:
            raise InvalidConfig(
                "--no-franka-realtime is the franka backend's; accepted with --backend franka"
            )
        if self.backend != "mujoco" and any(v for v in sim.values()):
            raise InvalidConfig(
                "--realtime, --latency, --joint-noise, --object-noise, --drop-rate are mujoco's"
            )
        backend = make_backend(
            self.backend,
            self.export_dir,
            self.address,
            sim if self.backend == "mujoco" else {},
            franka_realtime=self.franka_realtime,
        )
        if self.backend == "franka" and not self.franka_realtime:
            print("franka: realtime kernel not required (--no-franka-realtime: for a simulator, not the arm)")
        options = ControllerOptions(
            speed_scale=self.speed_scale,
            action_filter=self.action_filter,
            servo_period=backend.period,
            ramp=self.ramp,
        )
        controller = Controller.from_export(self.export_dir, options)
        if goal is not None:
            controller.check_goal(goal)  # finite, its size, inside the workspace: before the arm moves
        check_backend(backend, controller.contract)  # before the log: a mismatch leaves nothing behind
        if self.dry_run:
            backend = ShadowBackend(backend)
        seeds = list(self.seeds) if self.seeds is not None else list(range(self.episodes))
        header = log_header(self.export_dir, backend, options, {"servo": self.servo, "dry_run": self.dry_run})
        log = DeployLog(self.log, header)
        signals = StopSignals()
        try:
            with signals:
                results = run_episodes(
                    controller,
                    backend,
                    seeds,
                    [goal] * len(seeds) if goal is not None else None,
                    log,
                    self.servo,
                    stop=lambda: _stop_reason(signals.caught),
                )
        finally:
            log.close()
        for i, r in enumerate(results):
            true = (
                "" if r.true_success is None else f", simulator: {'success' if r.true_success else 'failure'}"
            )
            faults = ", ".join(f"{k} x{v}" for k, v in sorted(r.faults.items())) or "none"
            timing = "" if r.timing is None else f"; {r.timing.summary()}"
            print(
                f"episode {i} (seed {r.seed}): {'success' if r.success else 'failure'}{true}, final distance "
                f"{r.distance:.4f} m, faults: {faults}{timing}"
            )
        stopped = next((r.stopped for r in results if r.stopped is not None), None)
        if stopped is not None:
            by = "" if signals.caught else " by the safety layer"
            print(f"stopped{by} in episode {len(results) - 1}: {stopped}")
        compute = np.concatenate([r.compute_s for r in results]) * 1e3
        interp = np.concatenate([r.interpolate_s for r in results]) * 1e6
        wins = sum(r.success for r in results)
        timings = [r.timing for r in results if r.timing is not None]
        unpaced = self.backend == "mujoco" and not self.realtime
        loop = f"{worst_of(timings)}{' (simulator unpaced; --realtime paces it)' if unpaced else ''}; "
        print(
            f"success {wins}/{len(results)}; controller per policy step p50 {np.percentile(compute, 50):.3f} ms, "
            f"p99 {np.percentile(compute, 99):.3f} ms; interpolate p99 {np.percentile(interp, 99):.1f} us; "
            f"{loop}log: {self.log}" + (" (dry run: nothing was sent)" if self.dry_run else "")
        )
        if signals.caught:
            return 128 + signals.caught[0]
        return 0 if stopped is None else 1

    def _replay(self) -> int:
        from .loop import replay

        assert self.replay is not None
        result = replay(self.replay, self.video, every=self.video_every)
        print(
            f"replayed {result.cycles} policy steps of {self.replay}: largest difference from the log: joint "
            f"target {result.max_target_difference:.3g} rad, action {result.max_action_difference:.3g}, servo "
            f"command {result.max_servo_difference:.3g} rad; video: {result.video}"
            + (
                ""
                if result.ends_early is None
                else f"; the log ends early ({result.ends_early}): its complete records were replayed"
            )
        )
        return 0 if result.max_target_difference <= 1e-9 and result.max_servo_difference <= 1e-9 else 1


def check_log_path(path: Path) -> None:
    """Raises InvalidConfig unless `path` can be written as a file: not a folder, and its nearest
    existing parent folder writable (the folders between are created with the first record)."""
    import os

    if path.is_dir():
        raise InvalidConfig(f"--log {path} is a folder; give a file path, e.g. {path / 'deploy.jsonl'}")
    if path.exists() and not os.access(path, os.W_OK):
        raise InvalidConfig(f"--log {path} is not writable")
    parent = path.absolute().parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir() or not os.access(parent, os.W_OK | os.X_OK):
        raise InvalidConfig(f"--log {path}: {parent} is not a writable folder")


def _parse_goal(text: str | None) -> tuple[float, ...] | None:
    """--goal x,y,z (comma-separated numbers)."""
    if text is None:
        return None
    try:
        return tuple(float(v) for v in text.split(","))
    except ValueError:
        raise InvalidConfig(
            f"--goal must be comma-separated numbers, e.g. -0.5,-0.1,0.3; got {text!r}"
        ) from None


#: The commands tsrl.cli adds.
DEPLOY_COMMANDS: dict[str, type] = {"export": Export, "deploy": Deploy}


def _stop_reason(caught: list[int]) -> str | None:
    """The deployment's stop reason once an operator's signal was noted (tsrl.signals.StopSignals)."""
    return f"{signal.Signals(caught[0]).name}: stopped on the operator's signal" if caught else None
