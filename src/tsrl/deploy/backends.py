"""One robot interface (`RobotBackend`) and its backends: a simulated arm in MuJoCo, UR (ur-rtde),
Franka (franky-control), and shadow mode (`ShadowBackend`: reads, sends nothing).

A backend reads the arm's state, takes joint position commands, and paces the servo loop at its
period. `check_backend(backend, contract)` refuses one whose joints differ from the contract's.

`MujocoBackend` is the stand-in for hardware: a separate MuJoCo model of the arm (the export's scene,
or another model file of the same arm) stepped one physics step per servo period, as fast as
possible or in real time, with injectable command latency, observation noise and dropped messages;
its clock is the simulation's. `UrRtdeBackend` and `FrankaBackend` are thin wrappers over their
libraries' documented calls, imported when connected; they have not been tried on a robot
(docs/deploy.md).
"""

from __future__ import annotations

import collections
import math
import time
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import mujoco
import numpy as np

from ..assets import panda, ur5e
from ..exceptions import InvalidAction, InvalidConfig, TsrlError
from ..kinematics import arm_dof_indices, name_to_id
from .contract import Contract, read_contract
from .exported import exported_env


class BackendError(TsrlError):
    """A robot that does not answer, or a backend library that is missing: the arm was not moved."""


class RobotState(NamedTuple):
    """What a backend measured: at `time` [s, the backend's clock], joint positions q (n,) [rad],
    velocities qd (n,) [rad/s], object poses by body (7,) or (13,), and the gripper's opening width
    [m] or None (tsrl.deploy.Controller.act)."""

    time: float
    q: np.ndarray
    qd: np.ndarray
    objects: dict[str, np.ndarray]
    tool: float | None = None


class RobotBackend(Protocol):
    """A robot: `joint_names` (its joints, in the order of q), `period` (its servo period [s])."""

    name: str
    joint_names: tuple[str, ...]
    period: float

    def connect(self) -> None:
        """Opens the connection (BackendError if the robot does not answer)."""

    def now(self) -> float:
        """The backend's clock [s]."""

    def read_state(self) -> RobotState:
        """The latest measured state."""

    def send(self, q: np.ndarray, tool: float | None = None) -> str | None:
        """A joint position command (n,) for this servo period, and the tool command if any (the tool
        actuator's control value: suction 1 on / 0 off, a gripper's target width [m];
        Controller.tool). Returns None, or why the robot refused the command (one line): a fault the
        safety layer handles (tsrl.deploy.safety.RefusedCommands)."""

    def wait(self) -> None:
        """Returns at the start of the next servo period."""

    def reset(self, seed: int | None) -> None:
        """A new episode: a simulator draws the task's start state; a real arm stays where it is."""

    def close(self) -> None:
        """Stops the arm's servoing and closes the connection."""


def check_backend(backend: RobotBackend, contract: Contract) -> None:
    """Raises InvalidConfig (one line) unless the backend's joints are the contract's, in order."""
    expected = list(contract.robot.joints)
    actual = list(backend.joint_names)
    if actual != expected:
        raise InvalidConfig(
            f"backend {backend.name} has joints {actual} ({len(actual)}); the contract's robot has "
            f"{expected} ({len(expected)}); the arm was not moved"
        )


class MujocoBackend:
    """A simulated arm (module docstring); deterministic given `seed` (noise, drops).

    Args:
        export_dir: the export folder (its scene, robot and task); scene: another model file of the
            same arm, or None for the exported scene.
        realtime: pace the servo loop to the wall clock (else as fast as possible).
        latency: seconds [s] before a command reaches the servos (rounded to servo periods).
        joint_noise: standard deviation [rad] of Gaussian noise on measured joint positions.
        object_noise: standard deviation [m] of Gaussian noise on measured object positions.
        drop_rate: probability that a command is lost (the servos keep the last one) and that a state
            read returns the previous state again (stale: the controller's guard holds).
    """

    name = "mujoco"

    def __init__(
        self,
        export_dir: Path | str,
        scene: Path | str | None = None,
        *,
        realtime: bool = False,
        latency: float = 0.0,
        joint_noise: float = 0.0,
        object_noise: float = 0.0,
        drop_rate: float = 0.0,
        seed: int = 0,
    ):
        for key, value in (
            ("latency", latency),
            ("joint_noise", joint_noise),
            ("object_noise", object_noise),
        ):
            if not value >= 0:
                raise InvalidConfig(f"{key} must be >= 0; got {value}")
        if not 0 <= drop_rate < 1:
            raise InvalidConfig(f"drop_rate must be in [0, 1); got {drop_rate}")
        contract = read_contract(export_dir)
        self.env = exported_env(export_dir, contract, scene)
        self.model, self.data = self.env.model, self.env.data
        robot = self.env.bound_robot
        self.joint_names: tuple[str, ...] = robot.joints
        self.period = float(self.model.opt.timestep)
        self.realtime = realtime
        self._qpos, self._ctrl = robot.qpos, robot.ctrl
        self._dofs = arm_dof_indices(self.model, robot.joints)
        self._tool_ctrl = self.env.interface.tool_ctrl
        self._objects: dict[str, tuple[int, int]] = {}
        for obj in self.env.task.objects:
            joint = self.model.body_jntadr[name_to_id(self.model, "body", obj.body)]
            self._objects[obj.body] = (int(self.model.jnt_qposadr[joint]), int(self.model.jnt_dofadr[joint]))
        self._delay = round(latency / self.period)
        self.joint_noise, self.object_noise, self.drop_rate = joint_noise, object_noise, drop_rate
        self._rng = np.random.default_rng(seed)
        self._queue: collections.deque[tuple[np.ndarray, float | None]] = collections.deque()
        self._last_state: RobotState | None = None
        self._wall_start = 0.0
        self._sim_start = 0.0
        #: Commands the servos received (after latency and drops), one per servo period.
        self.applied = 0

    def connect(self) -> None:
        self._wall_start, self._sim_start = time.perf_counter(), self.data.time

    def now(self) -> float:
        return float(self.data.time)

    def reset(self, seed: int | None) -> None:
        self.env.reset(seed=seed)
        self._queue.clear()
        self._last_state = None
        self._wall_start, self._sim_start = time.perf_counter(), self.data.time

    def read_state(self) -> RobotState:
        if self._last_state is not None and self.drop_rate and self._rng.random() < self.drop_rate:
            return self._last_state  # the message was lost: the last one again
        q = self.data.qpos[self._qpos].copy()
        if self.joint_noise:
            q += self._rng.normal(0.0, self.joint_noise, q.shape)
        objects = {}
        for body, (qadr, dadr) in self._objects.items():
            state = np.concatenate([self.data.qpos[qadr : qadr + 7], self.data.qvel[dadr : dadr + 6]])
            if self.object_noise:
                state[:3] += self._rng.normal(0.0, self.object_noise, 3)
            objects[body] = state
        width = self.env.interface.measure_tool(self.data)
        self._last_state = RobotState(self.now(), q, self.data.qvel[self._dofs].copy(), objects, width)
        return self._last_state

    def send(self, q: np.ndarray, tool: float | None = None) -> str | None:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (len(self.joint_names),) or not np.isfinite(q).all():
            raise InvalidAction(f"joint command {q!r} is not {len(self.joint_names)} finite values; not sent")
        if self.drop_rate and self._rng.random() < self.drop_rate:
            return None  # lost on the way (unnoticed, as a lost message is)
        self._queue.append((q.copy(), tool))
        return None

    def wait(self) -> None:
        """Applies the command due now (after `latency`), then one physics step; paced in real time."""
        while len(self._queue) > self._delay:
            q, tool = self._queue.popleft()
            self.data.ctrl[self._ctrl] = q
            if tool is not None and self._tool_ctrl is not None:
                self.data.ctrl[self._tool_ctrl] = tool
            self.applied += 1
        mujoco.mj_step(self.model, self.data)
        if self.realtime:
            ahead = (self.data.time - self._sim_start) - (time.perf_counter() - self._wall_start)
            if ahead > 0:
                time.sleep(ahead)

    def place_goal_marker(self, goal: np.ndarray) -> None:
        """Shows the goal (g,) in the simulated scene (the marker has no collisions)."""
        self.env.goal.place(self.data, np.asarray(goal, dtype=np.float64))

    def outcome(self) -> dict[str, Any]:
        """The task's goal info (is_success, distance, ...) of the simulated arm's true state."""
        self.env.plan.evaluate(self.model, self.data)
        _, achieved, desired = self.env.plan.views
        return self.env.goal.outcome(achieved, desired)[1]

    def close(self) -> None:
        self.env.close()


class ShadowBackend:
    """Shadow mode (`--dry-run`): reads and paces like `backend`, computes nothing of its own, and sends
    no command; `sent` counts what would have been sent."""

    def __init__(self, backend: RobotBackend):
        self.backend = backend
        self.name = f"{backend.name} (dry run)"
        self.joint_names = backend.joint_names
        self.period = backend.period
        self.sent = 0

    def connect(self) -> None:
        self.backend.connect()

    def now(self) -> float:
        return self.backend.now()

    def read_state(self) -> RobotState:
        return self.backend.read_state()

    def send(self, q: np.ndarray, tool: float | None = None) -> str | None:
        self.sent += 1  # logged by the deploy loop; never forwarded
        return None

    def wait(self) -> None:
        self.backend.wait()

    def reset(self, seed: int | None) -> None:
        self.backend.reset(seed)

    def close(self) -> None:
        self.backend.close()


def _import(module: str, extra: str, package: str) -> Any:
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise BackendError(f"the {extra} backend needs {package}: pip install 'tsrl[{extra}]'") from None


class UrRtdeBackend:
    """A Universal Robots arm over ur-rtde: `servoJ` at 500 Hz (untried on hardware; docs/deploy.md).

    Calls (ur-rtde's documented Python API): RTDEReceiveInterface.getActualQ / getActualQd /
    getTimestamp; RTDEControlInterface.initPeriod, servoJ(q, velocity, acceleration, dt,
    lookahead_time, gain), waitPeriod, servoStop, stopScript. No objects: a reach task only.
    """

    name = "ur"
    joint_names: tuple[str, ...] = ur5e.JOINT_NAMES  # base, shoulder, elbow, wrist 1-3: UR's order

    def __init__(self, address: str, period: float = 0.002, lookahead_time: float = 0.1, gain: float = 300.0):
        self.address, self.period = address, period
        self.lookahead_time, self.gain = lookahead_time, gain
        self._control: Any = None
        self._receive: Any = None
        self._t_start: Any = None
        self._clock0 = 0.0

    def connect(self) -> None:
        rtde_control = _import("rtde_control", "ur", "ur-rtde")
        rtde_receive = _import("rtde_receive", "ur", "ur-rtde")
        try:
            self._receive = rtde_receive.RTDEReceiveInterface(self.address)
            self._control = rtde_control.RTDEControlInterface(self.address)
        except RuntimeError as err:
            raise BackendError(
                f"ur backend: no answer from {self.address} ({err}); the arm was not moved"
            ) from None
        self._clock0 = time.perf_counter()
        self._t_start = self._control.initPeriod()

    def now(self) -> float:
        return time.perf_counter() - self._clock0

    def read_state(self) -> RobotState:
        q = np.asarray(self._receive.getActualQ(), dtype=np.float64)
        qd = np.asarray(self._receive.getActualQd(), dtype=np.float64)
        return RobotState(self.now(), q, qd, {})

    def send(self, q: np.ndarray, tool: float | None = None) -> str | None:
        # velocity and acceleration are unused by servoJ (ur-rtde's documentation); dt is the period.
        ok = self._control.servoJ(list(map(float, q)), 0.0, 0.0, self.period, self.lookahead_time, self.gain)
        return "ur-rtde's servoJ returned false" if ok is False else None

    def wait(self) -> None:
        self._control.waitPeriod(self._t_start)
        self._t_start = self._control.initPeriod()

    def reset(self, seed: int | None) -> None:
        return None  # a real arm starts where it is

    def close(self) -> None:
        if self._control is not None:
            self._control.servoStop()
            self._control.stopScript()


#: How long FrankaBackend.close waits for the hand's last command [s] (the hand's full stroke at its
#: slowest is a few seconds).
HAND_DONE_S = 10.0


class FrankaBackend:
    """A Franka arm over franky-control: joint position motions (untried on hardware; docs/deploy.md).

    Each new command is `robot.move(JointMotion(q), asynchronous=True)`, which franky re-plans at once
    (Ruckig, within the arm's limits times `relative_dynamics_factor`); a command equal to the last one
    sent is not sent again (the motion already heads there). A command franky refuses (e.g. "Motion
    planner failed") is counted in `failed_commands`, franky's error recovery runs, the next command is
    sent afresh, and `send` returns franky's message: a fault the deploy loop's safety layer handles
    (tsrl.deploy.safety.RefusedCommands: hold, count, stop after several in a row). State from
    `robot.current_joint_state` (position, velocity). No objects: a reach task, or a gripper task
    whose objects another source measures.

    With `gripper` (a task with a gripper dimension: the Franka Hand, franky's `Gripper` on the same
    address), the state's `tool` is the hand's opening width `Gripper.width` [m], and a tool command
    (a target width [m], Controller.tool) that differs from the last one sent by more than
    `gripper_tolerance` is sent without waiting: opening with `move_async(width, gripper_speed)`,
    closing with `grasp_async(width, gripper_speed, gripper_force, MAX_WIDTH, MAX_WIDTH)` (the fingers
    close to the width or onto what lies between them, holding `gripper_force`; any final width is
    accepted). One hand command at a time: while the last one runs (its future not ready), a new
    width waits, and the latest is sent once the hand is done. A width that is not finite or outside [0, MAX_WIDTH] is not sent (InvalidAction); one
    franky refuses is a fault as a refused joint command is. The hand is left as it is on close (a
    grasped object stays held).

    Args:
        realtime: require a realtime kernel, as libfranka does by default (`RealtimeConfig.Enforce`);
            False (`Ignore`) for a simulator of the arm (franky-sim) on an ordinary kernel.
    """

    name = "franka"
    joint_names: tuple[str, ...] = panda.JOINT_NAMES

    def __init__(
        self,
        address: str,
        period: float = 0.01,
        relative_dynamics_factor: float = 0.1,
        realtime: bool = True,
        *,
        gripper: bool = False,
        gripper_speed: float = 0.1,
        gripper_force: float = panda.GRASP_FORCE,
        gripper_tolerance: float = 0.005,
    ):
        self.address, self.period = address, period
        self.relative_dynamics_factor = relative_dynamics_factor
        self.realtime = realtime
        self.gripper = gripper
        for key, value in (("gripper_speed", gripper_speed), ("gripper_force", gripper_force)):
            if not (math.isfinite(value) and value > 0):
                raise InvalidConfig(f"{key} must be finite and > 0; got {value}")
        if not (math.isfinite(gripper_tolerance) and gripper_tolerance >= 0):
            raise InvalidConfig(f"gripper_tolerance must be finite and >= 0; got {gripper_tolerance}")
        self.gripper_speed, self.gripper_force = gripper_speed, gripper_force
        self.gripper_tolerance = gripper_tolerance
        #: Commands franky refused (each followed by its error recovery).
        self.failed_commands = 0
        self._franky: Any = None
        self._robot: Any = None
        self._hand: Any = None
        self._sent: np.ndarray | None = None
        self._width_sent: float | None = None
        self._width_asked: float | None = None  # the last width sent, kept on a refusal: closing or opening
        self._hand_busy: Any = None  # the future of the hand's last command
        self._next = 0.0
        self._clock0 = 0.0

    def connect(self) -> None:
        self._franky = _import("franky", "franka", "franky-control")
        config = self._franky.RealtimeConfig
        try:
            self._robot = self._franky.Robot(
                self.address, realtime_config=config.Enforce if self.realtime else config.Ignore
            )
            self._robot.recover_from_errors()
            self._hand = self._franky.Gripper(self.address) if self.gripper else None
        except self._franky.RealtimeException as err:
            raise BackendError(
                f"franka backend: libfranka refuses to run without a realtime kernel ({err}); on the arm's "
                "computer use a realtime kernel; for a simulator (franky-sim) pass --no-franka-realtime; "
                "the arm was not moved"
            ) from None
        except Exception as err:  # noqa: BLE001  (libfranka's network errors are several classes)
            raise BackendError(
                f"franka backend: no answer from {self.address} ({err}); the arm was not moved"
            ) from None
        self._robot.relative_dynamics_factor = self.relative_dynamics_factor
        self._sent = self._width_sent = self._width_asked = self._hand_busy = None
        self._clock0 = time.perf_counter()
        self._next = self.period

    def now(self) -> float:
        return time.perf_counter() - self._clock0

    def read_state(self) -> RobotState:
        state = self._robot.current_joint_state
        width = float(self._hand.width) if self._hand is not None else None
        return RobotState(
            self.now(),
            np.asarray(state.position, np.float64),
            np.asarray(state.velocity, np.float64),
            {},
            width,
        )

    def send(self, q: np.ndarray, tool: float | None = None) -> str | None:
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (len(self.joint_names),) or not np.isfinite(q).all():
            raise InvalidAction(f"joint command {q!r} is not {len(self.joint_names)} finite values; not sent")
        if self._hand is not None and tool is not None and not 0 <= tool <= panda.MAX_WIDTH:  # NaN too
            raise InvalidAction(f"gripper width {tool!r} is not in [0, {panda.MAX_WIDTH}] m; not sent")
        why = self._send_joints(q)
        if self._hand is not None and tool is not None:
            refused = self._send_width(float(tool))
            why = refused if why is None else why if refused is None else f"{why}; {refused}"
        return why

    def _send_joints(self, q: np.ndarray) -> str | None:
        if self._sent is not None and np.array_equal(q, self._sent):
            return None  # a held target: the motion already heads there
        try:
            self._robot.move(self._franky.JointMotion(q.tolist()), asynchronous=True)
        except (self._franky.Exception, RuntimeError) as err:  # franky's planner errors are RuntimeErrors
            self.failed_commands += 1
            self._sent = None  # the next command is sent afresh
            self._robot.recover_from_errors()
            return f"franky: {_one_line(err)}"
        self._sent = q.copy()
        return None

    def _send_width(self, width: float) -> str | None:
        """The hand toward `width` [m] (class docstring), unless the last width sent is within the
        tolerance; franky's refusal (one line) or None."""
        last, previous = self._width_sent, self._width_asked
        if last is not None and abs(width - last) <= self.gripper_tolerance:
            return None  # held: the fingers already head there
        if self._hand_busy is not None and not self._hand_busy.wait(0.0):
            return None  # the hand is still at its last command: this width is sent once it is done
        try:
            if previous is not None and width < previous:  # closing: onto what lies between the fingers
                wide = panda.MAX_WIDTH
                future = self._hand.grasp_async(width, self.gripper_speed, self.gripper_force, wide, wide)
            else:
                future = self._hand.move_async(width, self.gripper_speed)
        except (self._franky.Exception, self._franky.GripperException, RuntimeError) as err:
            self.failed_commands += 1
            self._width_sent = None  # the next width is sent afresh
            return f"franky gripper: {_one_line(err)}"
        self._width_sent = self._width_asked = width
        self._hand_busy = future
        return None

    def wait(self) -> None:
        ahead = self._next - self.now()
        if ahead > 0:
            time.sleep(ahead)
        self._next += self.period

    def reset(self, seed: int | None) -> None:
        return None

    def close(self) -> None:
        """Stops the motion and drops the connection (libfranka closes it with the robot object); a stop
        franky refuses (the arm stopped on its error already) is followed by its error recovery. The
        hand's last command is waited for (HAND_DONE_S at most) before its connection is dropped."""
        if self._robot is not None:
            try:
                self._robot.move(self._franky.JointStopMotion())
            except (self._franky.Exception, RuntimeError):
                self._robot.recover_from_errors()
            finally:
                if self._hand_busy is not None:  # franky must not lose a hand whose command still runs
                    self._hand_busy.wait(HAND_DONE_S)
                self._robot = self._hand = self._hand_busy = None


def _one_line(err: BaseException) -> str:
    """An exception's message on one line (its type where it has none)."""
    text = " ".join(str(err).split())
    return text or type(err).__name__


#: Backend names of `tsrl deploy --backend`.
BACKENDS: tuple[str, ...] = ("mujoco", "ur", "franka")


def make_backend(
    name: str, export_dir: Path, address: str | None, options: dict[str, Any], franka_realtime: bool = True
) -> RobotBackend:
    """The backend called `name` (BACKENDS); ur and franka need an address; `franka_realtime`:
    FrankaBackend's `realtime`; franka drives the Franka Hand where the export's task has a gripper."""
    if name == "mujoco":
        return MujocoBackend(export_dir, **options)
    if name in ("ur", "franka"):
        if not address:
            raise InvalidConfig(f"--backend {name} needs --address (the robot's IP address)")
        if name == "ur":
            return UrRtdeBackend(address)
        tool = read_contract(export_dir).action.tool
        gripper = tool is not None and tool.kind == "gripper"
        return FrankaBackend(address, realtime=franka_realtime, gripper=gripper)
    raise InvalidConfig(f"unknown backend {name!r}; accepted: {', '.join(BACKENDS)}")
