"""TaskInterface: a task's task-space interface on one model, shared by training and the robot.

It owns what stands between a state and an action in both places: the step plan (every task map of
the step evaluated once), the action map with its tool dimension (suction or gripper), the policy's
previous actions and the IK step. `observe(model, data)` gives the step's observation and goals;
`command(action, q, data)` the joint targets and the tool command. `TaskEnv.step` (on its physics)
and the deployment `Controller` (on a measured state written into its own MjData) both call it, so
the robot runs the step the policy was trained with.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..ik import DlsSolver, IKOptions
from ..robots import BoundRobot, Robot
from ..taskmaps import Stack
from .actions import ActionMap
from .goals import Goal
from .observations import StepPlan, push_previous_action
from .tasks import Task


class Command(NamedTuple):
    """What one action commands.

    Attributes:
        q_target: joint targets (n,) [rad or m], the IK's (or the joint actions') servo targets.
        ik_error: the IK residual at q_target (0 for joint actions and the single step's).
        ik_target: the IK map's target (a live buffer; copy to keep), or None for joint actions.
        tool: the tool actuator's control value (suction: 1 on, 0 off; gripper: the servo's target
            opening width [m]), or None for a task without a tool dimension.
    """

    q_target: np.ndarray
    ik_error: float
    ik_target: np.ndarray | None
    tool: float | None


class TaskInterface:
    """A task's step plan, action map (tool included), previous actions and IK on one model.

    Args:
        task: the task (its observation and action already resolved: `Task.with_overrides`).
        model: the compiled scene; bound_robot: its robot bound to the model.
        obs_spec: the observation's task-map spec (a preset's expansion).
        ik_iterations: 1 = the single linearised IK step per control step; more = a local solve.
    """

    def __init__(
        self,
        task: Task,
        model: mujoco.MjModel,
        bound_robot: BoundRobot,
        obs_spec: str,
        ik_iterations: int = 1,
    ):
        self.task = task
        self.model = model
        self.bound_robot = bound_robot
        self.robot: Robot = bound_robot.robot
        spec = task.action_spec
        self.action_map = ActionMap(spec, model, len(self.robot.joints))
        if spec.suction and bound_robot.suction_ctrl is None:
            raise InvalidConfig(
                f"the task's action has suction, but robot {self.robot.name!r} has no suction actuator"
            )
        #: The tool's actuator (ctrl index), or None: the suction cup's or the gripper's servo.
        self.tool_ctrl: int | None = bound_robot.suction_ctrl if spec.suction else None
        # width at a = -1 and per unit of the gripper command [m], or None
        self._gripper: tuple[float, float] | None = None
        # the gripper servo's joints: (qpos address, dof address, gear x coefficient) each
        self._finger_joints: list[tuple[int, int, float]] = []
        if spec.gripper:
            g = bound_robot.gripper_ctrl
            if g is None:
                raise InvalidConfig(
                    f"the task's action has a gripper dimension, but robot {self.robot.name!r} has no gripper"
                )
            low, high = model.actuator_ctrlrange[g]
            self.tool_ctrl = g
            self._gripper = (float(low), float(high - low) / 2)
            self._finger_joints = _transmission_joints(model, g)
        self.goal = Goal(task, model, self.robot.joints)
        self.plan = StepPlan(model, obs_spec, self.goal, self.action_map.ik_map, self.robot.joints)
        self.goal.check_relabelable(self.plan.obs_map)
        self.ik_iterations = ik_iterations
        #: The IK's options: a single step per period, or a local solve of ik_iterations steps, with
        #: the redundant arm's null-space posture.
        self.ik_options = IKOptions(max_iters=ik_iterations, restarts=0, posture=bound_robot.posture)
        ik_map = self.action_map.ik_map
        self._ik = DlsSolver(model, ik_map, self.robot.joints, self.ik_options) if ik_map else None
        self._ik_data = mujoco.MjData(model)  # IK workspace: the caller's state is never touched by it
        #: The policy's last `task.previous_actions` actions (n, k), newest first: observation rows.
        self.previous_actions = np.zeros((task.previous_actions, self.action_map.dim))
        #: Rows of the "observation" entry: the observation map's, then the previous actions'.
        self.obs_dim: int = self.plan.obs_map.dim + self.previous_actions.size
        bound_robot.reset_to_home(model, self._ik_data)
        mujoco.mj_kinematics(model, self._ik_data)
        mujoco.mj_comPos(model, self._ik_data)
        self.action_map.check_holds(model, self._ik_data, self.robot.joints)

    @property
    def obs_map(self) -> Stack:
        """The observation's multi task map."""
        return self.plan.obs_map

    def observe(
        self, model: mujoco.MjModel, data: mujoco.MjData, kinematics: bool = True
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Evaluates every task map of the step once at the state in `data` (`kinematics`: run
        mj_kinematics and mj_comPos first); returns live views (observation map's rows (d,),
        achieved goal (g,), desired goal (g,)): copy before keeping them."""
        self.plan.evaluate(model, data, kinematics)
        return self.plan.views

    def observation(self, rows: np.ndarray) -> np.ndarray:
        """The observation entry: the observation map's rows (d,), then the previous actions (a copy)."""
        if self.previous_actions.size:
            return np.concatenate([rows, self.previous_actions.ravel()])
        return rows.copy()

    def reset(self) -> None:
        """An episode's start: no previous actions (zeros)."""
        self.previous_actions[:] = 0.0

    def remember(self, action: np.ndarray) -> None:
        """Records an applied action (k,) as the newest previous action."""
        push_previous_action(self.previous_actions, action)

    def command(self, action: np.ndarray, q: np.ndarray, data: mujoco.MjData) -> Command:
        """The joint targets and tool command of an action (k,) in [-1, 1] at the arm's joint positions
        q (n,), after `observe` of the state in `data` (whose qpos a local IK solve starts from)."""
        tool = self.tool(action)
        if self._ik is None:
            return Command(
                self.action_map.joint_targets(q, action, self.bound_robot.joint_range), 0.0, None, tool
            )
        initial = self.plan.ik_value
        assert initial is not None  # the plan evaluates the IK map whenever the action has one
        target = self.action_map.ik_target(action, initial.y)
        if self.ik_iterations == 1:  # the paper's single linearised step, on this step's Jacobian
            q_target, error = self._ik.step(q, initial, target)
            return Command(q_target, error, target, tool)
        self._ik_data.qpos[:] = data.qpos
        result = self._ik.solve(self._ik_data, target, initial)  # a local solve from the current pose
        return Command(result.q, result.error_norm, target, tool)

    def measure_tool(self, data: mujoco.MjData) -> float | None:
        """The gripper's opening width [m] at the state in `data` (gripperWidth: the servo's
        transmission length, sum of gear x coefficient x joint position); None without a gripper."""
        if not self._finger_joints:
            return None
        return float(sum(k * data.qpos[qadr] for qadr, _, k in self._finger_joints))

    def write_tool(self, data: mujoco.MjData, width: float) -> None:
        """Writes a measured opening width [m] into `data`: every finger joint at the same position
        (a symmetric grip, as a robot reports one width), at rest. No-op without a gripper."""
        if not self._finger_joints:
            return
        q = width / sum(k for _, _, k in self._finger_joints)
        for qadr, dadr, _ in self._finger_joints:
            data.qpos[qadr] = q
            data.qvel[dadr] = 0.0

    def tool(self, action: np.ndarray) -> float | None:
        """The tool actuator's control value for an action (k,): suction on (1) above 0, else off (0);
        a gripper's target width low + (a + 1) / 2 (high - low), or with `gripper_open_close` high
        above 0 and low at or below it; None without a tool dimension."""
        if self.tool_ctrl is None:
            return None
        a = action[-1]
        if self._gripper is None:
            return 1.0 if a > 0 else 0.0
        low, half_span = self._gripper
        command = (1.0 if a > 0 else -1.0) if self.task.action_spec.gripper_open_close else a
        return low + (command + 1.0) * half_span


def _transmission_joints(model: mujoco.MjModel, actuator: int) -> list[tuple[int, int, float]]:
    """(qpos address, dof address, gear x coefficient) of each joint an actuator's length sums: its
    joint, or the joints of its fixed tendon (as gripperWidth reads them)."""
    gear = float(model.actuator_gear[actuator, 0])
    target = int(model.actuator_trnid[actuator, 0])
    if int(model.actuator_trntype[actuator]) == int(mujoco.mjtTrn.mjTRN_TENDON):
        adr, num = int(model.tendon_adr[target]), int(model.tendon_num[target])
        terms = [(int(model.wrap_objid[k]), float(model.wrap_prm[k])) for k in range(adr, adr + num)]
    else:
        terms = [(target, 1.0)]
    return [(int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j]), gear * c) for j, c in terms]
