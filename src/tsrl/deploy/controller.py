"""The deployment runtime: an exported policy driving joint targets, behind the safety layer.

`Controller.from_export(DIR)` verifies the folder (tsrl.deploy.contract) and builds, from its copies,
the run's task-space interface (tsrl.envs.interface, the one `TaskEnv.step` calls; tsrl.deploy.exported):
the step's task maps, the goal, the action map with its tool and the IK, evaluated on a MjData of the
controller's own with kinematics only (no physics).
One policy step, `act(q, qd, objects, goal, t=...)`:

1. guards: a joint reading, object pose or gripper width with NaN/inf, a missing object or gripper
   width (a gripper task), a state older than
   `max_state_age` or not newer than the last one: hold (stop as fast as the limits allow) and report;
2. features: the measured state written into the model (arm qpos and qvel, objects, the gripper's
   width, goal markers, the last tool command), `mj_kinematics` + `mj_comPos`, the env's step maps evaluated once;
   where the task observes its previous actions (`previous_actions = n`), the last n applied actions
   after them, newest first (zeros after `reset`; a held step applies none and keeps them);
3. the policy (onnxruntime; normaliser inside); a non-finite action: hold and report; the action
   clipped to [-1, 1], then the optional first-order filter;
4. the interface's command (the env's own: `ActionMap.ik_target`, the IK step with the run's IK
   options, the tool command), the TCP target within the task's workspace box;
5. the joint limiter (tsrl.deploy.safety): the target within the joint limits (less a margin); the
   servo-rate commands from `interpolate(t)` within the speed and acceleration limits; a command the
   robot refuses (`refused(t)`): hold until the next step.

Every step's inputs, features, action, targets and faults are in `controller.last` (a `Cycle`).
Imports numpy, mujoco and onnxruntime only (never torch or stable-baselines3).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..envs.interface import TaskInterface
from ..envs.randomization import Randomizer
from ..exceptions import InvalidConfig
from ..kinematics import arm_dof_indices, arm_qpos_indices, name_to_id
from .contract import POLICY, Contract, read_contract
from .exported import exported_interface
from .policy import OnnxPolicy
from .safety import COMMAND_REFUSED, JOINT_LIMIT, JointLimiter

#: Faults a step reports (`Cycle.faults`); those in HOLDS make it hold instead of acting.
NONFINITE_STATE = "nonfinite_state"
MISSING_OBJECT = "missing_object"
MISSING_TOOL = "missing_tool"
STALE_STATE = "stale_state"
NONFINITE_GOAL = "nonfinite_goal"
NONFINITE_ACTION = "nonfinite_action"
GOAL_OUTSIDE_WORKSPACE = "goal_outside_workspace"
WORKSPACE_CLIP = "workspace_clip"
HOLDS = frozenset(
    {NONFINITE_STATE, MISSING_OBJECT, MISSING_TOOL, STALE_STATE, NONFINITE_GOAL, NONFINITE_ACTION}
)


@dataclass(frozen=True)
class ControllerOptions:
    """Run-time settings of a Controller (the contract fixes everything else)."""

    speed_scale: float = 1.0
    """Scales the contract's joint speed and acceleration limits, in (0, 1] (0.25 for a first slow run)."""
    joint_margin: float = 0.01
    """Distance [rad or m] commands keep from each joint limit."""
    max_state_age: float | None = None
    """A state measured longer ago than this [s] is stale: hold. None: half a control period."""
    action_filter: float = 0.0
    """Time constant [s] of a first-order filter on the policy's action; 0: no filter."""
    servo_period: float | None = None
    """Period [s] of `interpolate` (the backend's); None: the model's physics timestep."""
    ramp: bool = False
    """Servo commands ramp to each policy target over the control period (smoother, up to a period
    late); default: toward the target at once, as fast as the limits allow (as training's servos)."""

    def __post_init__(self) -> None:
        if not 0 < self.speed_scale <= 1:
            raise InvalidConfig(f"speed_scale must be in (0, 1]; got {self.speed_scale}")
        if not self.joint_margin >= 0:
            raise InvalidConfig(f"joint_margin must be >= 0; got {self.joint_margin}")
        if self.max_state_age is not None and not self.max_state_age > 0:
            raise InvalidConfig(f"max_state_age must be > 0 s; got {self.max_state_age}")
        if not self.action_filter >= 0:
            raise InvalidConfig(f"action_filter must be >= 0 s; got {self.action_filter}")
        if self.servo_period is not None and not self.servo_period > 0:
            raise InvalidConfig(f"servo_period must be > 0 s; got {self.servo_period}")


@dataclass
class Cycle:
    """One policy step of the controller: what it read, computed and commanded (copies)."""

    t: float
    stamp: float | None
    q: np.ndarray
    qd: np.ndarray
    objects: dict[str, np.ndarray]
    goal: np.ndarray
    tool_width: float | None = None  # the measured gripper width [m]
    observation: np.ndarray | None = None
    achieved_goal: np.ndarray | None = None
    desired_goal: np.ndarray | None = None
    action: np.ndarray | None = None  # the policy's output
    applied_action: np.ndarray | None = None  # clipped to [-1, 1] and filtered
    ik_target: np.ndarray | None = None
    q_ik: np.ndarray | None = None
    q_target: np.ndarray | None = None
    suction: bool | None = None
    tool: float | None = None  # the tool command (TaskInterface.tool)
    faults: tuple[str, ...] = ()
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def held(self) -> bool:
        return any(f in HOLDS for f in self.faults)


class Controller:
    """An exported policy with its features, IK and safety layer (module docstring).

    Build it with `Controller.from_export(DIR)`.
    """

    def __init__(
        self, folder: Path, contract: Contract, interface: TaskInterface, options: ControllerOptions
    ):
        self.folder, self.contract, self.options = folder, contract, options
        #: The run's task-space interface (step plan, goal, action map and tool, previous actions, IK).
        self.interface = interface
        model = self.model = interface.model
        robot = contract.robot
        #: Joint names in the order of every joint vector the controller reads and writes.
        self.joint_names: tuple[str, ...] = robot.joints
        self.n = len(self.joint_names)
        self.control_period: float = contract.task.control_period_s
        self.servo_period: float = float(options.servo_period or model.opt.timestep)
        self.max_state_age = options.max_state_age or self.control_period / 2
        self.data = mujoco.MjData(model)
        interface.bound_robot.reset_to_home(model, self.data)
        self._qpos = arm_qpos_indices(model, self.joint_names)
        self._dofs = arm_dof_indices(model, self.joint_names)
        self._objects: dict[str, tuple[int, int]] = {}
        for obj in interface.task.objects:
            joint = model.body_jntadr[name_to_id(model, "body", obj.body)]
            self._objects[obj.body] = (int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint]))
        self.policy = OnnxPolicy(folder / POLICY, tuple(i.name for i in contract.policy.inputs))
        limits = np.asarray(robot.joint_limits, dtype=np.float64)
        unlimited = [
            j for j, (lo, hi) in zip(self.joint_names, limits) if not (np.isfinite(lo) and np.isfinite(hi))
        ]
        if unlimited:
            raise InvalidConfig(
                f"contract.json: joint {unlimited[0]!r} has no position limits; the safety layer needs finite "
                "limits on every joint (give them in the robot's model)"
            )
        scale = options.speed_scale
        self.limiter = JointLimiter(
            limits[:, 0] + options.joint_margin,
            limits[:, 1] - options.joint_margin,
            np.asarray(robot.max_joint_speed) * scale,
            np.asarray(robot.max_joint_acceleration) * scale,
            self.servo_period,
            self.control_period,
            options.ramp,
        )
        ws = contract.workspace
        self.workspace: tuple[np.ndarray, np.ndarray] | None = (
            (np.asarray(ws.low, dtype=np.float64), np.asarray(ws.high, dtype=np.float64))
            if ws is not None
            else None
        )
        # The TCP position part: its action columns, IK-target rows and step, to report workspace clips.
        self._tcp_part: tuple[slice, slice, float] | None = None
        ik_map = interface.action_map.ik_map
        if ws is not None and ik_map is not None:
            part = contract.action.parts[ws.part]
            if part.step is not None:  # a relative part: what the policy asked is y + step a
                rows = list(ik_map.slices.values())[ws.part]
                self._tcp_part = (slice(*part.columns), rows, part.step)
        self._alpha = math.exp(-self.control_period / options.action_filter) if options.action_filter else 0.0
        self._filtered: np.ndarray | None = None
        self._goal = np.zeros(interface.goal.dim)
        self._goal_set = False
        self._tool = self._tool_at_reset()
        self._gripper = interface.measure_tool(self.data) is not None
        self._last_stamp: float | None = None
        self._goal_sampler: tuple[Randomizer, mujoco.MjData] | None = None
        self.last: Cycle | None = None

    @classmethod
    def from_export(cls, folder: Path | str, options: ControllerOptions | None = None) -> Controller:
        """The controller of an export folder, after every file's sha256 and the contract's version
        are checked (ContractError: one line naming the file and what was expected)."""
        folder = Path(folder)
        contract = read_contract(folder)
        return cls(folder, contract, exported_interface(folder, contract), options or ControllerOptions())

    # -- episode ----------------------------------------------------------------------------------
    def reset(self, joint_positions: ArrayLike, t: float, goal: ArrayLike | None = None) -> None:
        """Starts an episode at rest at the measured joint positions (n,) at time t [s], optionally with
        its goal (g,); the filter, the previous actions and the tool command are reset."""
        q = self._joints("joint_positions", joint_positions)
        if not np.isfinite(q).all():
            raise InvalidConfig(f"reset: joint positions must be finite; got {q.tolist()}")
        self.limiter.reset(q, t)
        self._filtered = None
        self.interface.reset()
        self._tool = self._tool_at_reset()
        self._last_stamp = None
        if goal is not None:
            self.set_goal(goal)

    def set_goal(self, goal: ArrayLike) -> None:
        """The desired goal (g,) as the environment emits it (positions [m] in the world frame, then
        any orientation (w, x, y, z)); the goal's penalty columns, if any, may be left out."""
        g = np.asarray(goal, dtype=np.float64).reshape(-1)
        dim = self.interface.goal.dim
        penalties = len(self.interface.goal.penalties)
        if g.size == dim - penalties:
            g = np.concatenate([g, np.zeros(penalties)])  # a penalty's desired value is 0
        if g.shape != (dim,):
            raise InvalidConfig(f"goal has {g.size} values; the contract's goal has {dim}")
        self._goal = g
        self._goal_set = True

    def check_goal(self, goal: ArrayLike) -> None:
        """Raises InvalidConfig (one line) unless a goal given by hand (g,) is finite, of the contract's
        size, and its positions lie inside the contract's workspace box (where it has one)."""
        g = np.asarray(goal, dtype=np.float64).reshape(-1)
        if not np.isfinite(g).all():
            raise InvalidConfig(
                f"goal {g.tolist()} is not finite; give finite numbers [m] in the world frame"
            )
        self.set_goal(g)
        if self.workspace is not None and not self._goal_within_workspace():
            low, high = self.workspace
            raise InvalidConfig(
                f"goal {g.tolist()} lies outside the contract's workspace (low {low.tolist()}, high "
                f"{high.tolist()} m, world frame)"
            )

    def sample_goal(self, seed: int) -> np.ndarray:
        """A goal (g,) drawn as the task draws it at reset with this seed (the same as `tsrl evaluate`'s
        episode with that seed: the task's Randomizer with the generator gymnasium seeds `reset` with)."""
        from gymnasium.utils.seeding import np_random

        interface, model = self.interface, self.model
        if self._goal_sampler is None:
            randomizer = Randomizer(model, interface.task, interface.bound_robot, interface.goal)
            self._goal_sampler = (randomizer, mujoco.MjData(model))
        randomizer, data = self._goal_sampler
        interface.bound_robot.reset_to_home(model, data)
        randomizer.randomize(data, np_random(seed)[0])
        return interface.observe(model, data)[2].copy()

    # -- one policy step ------------------------------------------------------------------------------
    def act(
        self,
        joint_positions: ArrayLike,
        joint_velocities: ArrayLike,
        objects: Mapping[str, ArrayLike] | None = None,
        goal: ArrayLike | None = None,
        *,
        t: float,
        stamp: float | None = None,
        tool: float | None = None,
    ) -> np.ndarray:
        """One policy step at time t [s] from the state measured at `stamp` [s] (same clock; None: now).

        Args:
            joint_positions, joint_velocities: (n,) [rad, rad/s] in `joint_names` order.
            objects: body name -> (7,) pos [m] + quat (w, x, y, z), or (13,) with the free joint's
                qvel (linear [m/s] in world, angular [rad/s] in the body frame), world frame; one per
                task object.
            goal: the desired goal (g,), or None to keep the last one.
            tool: the gripper's measured opening width [m] (RobotState.tool); a gripper task needs it.

        Returns:
            The joint targets (n,) the limiter now moves toward (within the joint limits); the servo
            commands come from `interpolate`.
        """
        if not self.limiter.ready:
            raise InvalidConfig("Controller.reset(joint_positions, t) first: it starts at the measured pose")
        q = self._joints("joint_positions", joint_positions)
        qd = self._joints("joint_velocities", joint_velocities)
        if goal is not None:
            self.set_goal(goal)
        if not self._goal_set:
            raise InvalidConfig("no goal: pass goal= to act, reset or set_goal")
        objs = {k: np.asarray(v, dtype=np.float64).reshape(-1) for k, v in (objects or {}).items()}
        cycle = Cycle(t, stamp, q, qd, objs, self._goal.copy(), _width(tool))
        self.last = cycle
        faults = self._guards(cycle)
        if faults:
            return self._hold(cycle, faults)
        rows, achieved, desired = self._features(q, qd, objs, cycle.tool_width)
        observation = self.interface.observation(rows)
        cycle.observation, cycle.achieved_goal, cycle.desired_goal = (
            observation.copy(),
            achieved.copy(),
            desired.copy(),
        )
        cycle.info = self.interface.goal.outcome(achieved, desired)[1]
        action = self.policy({"observation": observation, "achieved_goal": achieved, "desired_goal": desired})
        cycle.action = action.copy()
        if not np.isfinite(action).all():
            return self._hold(cycle, (NONFINITE_ACTION,))
        a = np.minimum(np.maximum(action, -1.0), 1.0)  # np.clip costs twice as much
        if self._alpha:
            self._filtered = (
                a if self._filtered is None else self._alpha * self._filtered + (1 - self._alpha) * a
            )
            a = self._filtered
        cycle.applied_action = a.copy()
        self.interface.remember(a)
        found: list[str] = []
        if self.workspace is not None and not self._goal_within_workspace():
            found.append(GOAL_OUTSIDE_WORKSPACE)
        q_ik = self._command(q, a, cycle, found)
        cycle.q_ik = q_ik.copy()
        cycle.suction, cycle.tool = self.suction, self._tool
        q_target, clipped = self.limiter.set_target(q_ik, t)
        if clipped:
            found.append(JOINT_LIMIT)
        cycle.q_target = q_target
        cycle.faults = tuple(found)
        self._last_stamp = stamp
        return q_target.copy()

    def outcome(
        self,
        joint_positions: ArrayLike,
        joint_velocities: ArrayLike,
        objects: Mapping[str, ArrayLike] | None = None,
        tool: float | None = None,
    ) -> dict[str, Any]:
        """The task's goal info (is_success, distance [m], ...) of a measured state (and gripper width
        [m]) and the current goal, without acting (e.g. after an episode's last step)."""
        q = self._joints("joint_positions", joint_positions)
        qd = self._joints("joint_velocities", joint_velocities)
        objs = {k: np.asarray(v, dtype=np.float64).reshape(-1) for k, v in (objects or {}).items()}
        cycle = Cycle(0.0, None, q, qd, objs, self._goal.copy(), _width(tool))
        faults = self._guards(cycle)
        if faults:
            return {"is_success": False, "faults": faults}
        _, achieved, desired = self._features(q, qd, objs, cycle.tool_width)
        return self.interface.goal.outcome(achieved, desired)[1]

    def interpolate(self, t: float) -> np.ndarray:
        """The servo command (n,) at time t: one servo period further along toward the last target,
        within the joint, speed and acceleration limits (tsrl.deploy.safety)."""
        return self.limiter.step(t)

    def refused(self, t: float) -> None:
        """The robot refused the servo command of time t (tsrl.deploy.safety.RefusedCommands): the
        commands stop as fast as the limits allow and hold there until the next policy step, which
        acts afresh; the last step reports COMMAND_REFUSED."""
        self.limiter.hold(t)
        if self.last is not None and COMMAND_REFUSED not in self.last.faults:
            self.last.faults = (*self.last.faults, COMMAND_REFUSED)

    @property
    def suction(self) -> bool:
        """The suction command (on) of the last policy step (False without a suction cup)."""
        return self.contract.action.suction is not None and self._tool == 1.0

    @property
    def tool(self) -> float | None:
        """The tool actuator's command of the last policy step (TaskInterface.tool: suction 1/0, a
        gripper's target width [m]), or None for a task without a tool dimension."""
        return self._tool

    def _tool_at_reset(self) -> float | None:
        """The tool command an episode starts with: suction off, a gripper's servo as at home."""
        ctrl = self.interface.tool_ctrl
        if ctrl is None:
            return None
        if self.contract.action.suction is not None:
            return 0.0
        data = mujoco.MjData(self.model)
        self.interface.bound_robot.reset_to_home(self.model, data)
        return float(data.ctrl[ctrl])

    # -- internals ------------------------------------------------------------------------------------
    def _joints(self, name: str, value: ArrayLike) -> np.ndarray:
        v = np.asarray(value, dtype=np.float64).reshape(-1)
        if v.shape != (self.n,):
            raise InvalidConfig(f"{name} has {v.size} values; the contract's robot has {self.n} joints")
        return v

    def _guards(self, cycle: Cycle) -> tuple[str, ...]:
        faults = []
        if not (np.isfinite(cycle.q).all() and np.isfinite(cycle.qd).all()):
            faults.append(NONFINITE_STATE)
        for body in self._objects:
            pose = cycle.objects.get(body)
            if pose is None or pose.size not in (7, 13):
                faults.append(MISSING_OBJECT)
            elif not np.isfinite(pose).all():
                faults.append(NONFINITE_STATE)
        if self._gripper:
            if cycle.tool_width is None:
                faults.append(MISSING_TOOL)
            elif not math.isfinite(cycle.tool_width):
                faults.append(NONFINITE_STATE)
        if not np.isfinite(cycle.goal).all():
            faults.append(NONFINITE_GOAL)
        stamp = cycle.stamp
        if stamp is not None and (
            not math.isfinite(stamp)
            or cycle.t - stamp > self.max_state_age
            or (self._last_stamp is not None and stamp <= self._last_stamp)
        ):
            faults.append(STALE_STATE)
        return tuple(dict.fromkeys(faults))

    def _hold(self, cycle: Cycle, faults: tuple[str, ...]) -> np.ndarray:
        cycle.q_target = self.limiter.hold(cycle.t)
        cycle.suction, cycle.tool = self.suction, self._tool  # the tool command stays as it was
        cycle.faults = faults
        return cycle.q_target.copy()

    def _features(
        self, q: np.ndarray, qd: np.ndarray, objects: dict[str, np.ndarray], width: float | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The env's observation, achieved and desired goal (views) of a measured state: the state
        written into the controller's MjData, kinematics, every step map evaluated once."""
        self._write_state(q, qd, objects, width)
        return self.interface.observe(self.model, self.data)

    def _write_state(
        self, q: np.ndarray, qd: np.ndarray, objects: dict[str, np.ndarray], width: float | None
    ) -> None:
        data = self.data
        if width is not None:
            self.interface.write_tool(data, width)
        data.qpos[self._qpos] = q
        data.qvel[self._dofs] = qd
        for body, (qadr, dadr) in self._objects.items():
            pose = objects[body]
            data.qpos[qadr : qadr + 7] = pose[:7]
            data.qvel[dadr : dadr + 6] = pose[7:] if pose.size == 13 else 0.0
        self.interface.goal.place(data, self._goal)
        if self._tool is not None:
            data.ctrl[self.interface.tool_ctrl] = self._tool

    def _goal_within_workspace(self) -> bool:
        assert self.workspace is not None
        low, high = self.workspace
        for part in self.interface.goal.parts:
            p = self._goal[part.position]
            if (p < low).any() or (p > high).any():
                return False
        return True

    def _command(self, q: np.ndarray, a: np.ndarray, cycle: Cycle, found: list[str]) -> np.ndarray:
        """The joint positions (n,) the env's step commands for action a at q (the interface's), and
        the tool command."""
        command = self.interface.command(a, q, self.data)
        self._tool = command.tool
        target = command.ik_target
        if target is None:  # joint actions
            return command.q_target
        value = self.interface.plan.ik_value
        assert value is not None
        if self._tcp_part is not None and self.workspace is not None:
            cols, rows, step = self._tcp_part
            asked = value.y[rows] + step * a[cols]
            low, high = self.workspace
            if (asked < low).any() or (asked > high).any():
                found.append(WORKSPACE_CLIP)
            # the IK target is within the box already: it is the action part's bounds (ActionMap)
        cycle.ik_target = target.copy()
        return command.q_target


def _width(tool: float | None) -> float | None:
    """A measured gripper width as a float (NaN for a value that is not a number), or None."""
    if tool is None:
        return None
    try:
        return float(tool)
    except (TypeError, ValueError):
        return math.nan
