"""TaskEnv: the one goal-conditioned MuJoCo environment that builds any task (envs/tasks.py).

One step (the Gymnasium-Robotics skeleton): check the action, the action map sets the IK target,
IK -> servo targets, physics substeps, the task maps evaluated once (their values and Jacobians
reused for observation, goals, reward and the next step's IK), `compute_reward`.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from numpy.typing import ArrayLike

from ..exceptions import InvalidAction, InvalidConfig
from ..ik import DlsSolver, IKOptions
from ..kinematics import arm_qpos_indices, as_slice, joint_limits, name_to_id
from ..robots import Robot, load_robot
from ..taskmaps import Stack
from ..taskmaps.relabel import relabelled
from .actions import ACTION_PRESETS, ActionMap
from .observations import OBS_PRESETS, StepPlan
from .randomization import Randomizer
from .scenes import load_scene
from .tasks import Task, load_task

#: Physics warnings that mean the simulation blew up (MuJoCo resets the state when they fire).
_BADQACC, _BADQVEL, _BADQPOS = (
    int(w)
    for w in (
        mujoco.mjtWarning.mjWARN_BADQACC,
        mujoco.mjtWarning.mjWARN_BADQVEL,
        mujoco.mjtWarning.mjWARN_BADQPOS,
    )
)


def checked_action(action: ArrayLike, space: spaces.Box) -> np.ndarray:
    """A finite action of the space's shape, clipped to its bounds; NaN/inf is rejected."""
    return _checked_action(action, space.shape, space.low.astype(np.float64), space.high.astype(np.float64))


def _checked_action(
    action: ArrayLike, shape: tuple[int, ...], low: np.ndarray, high: np.ndarray
) -> np.ndarray:
    """`checked_action` with the space's bounds already in float64 (a step clips with them)."""
    a = np.asarray(action, dtype=np.float64)
    if a.shape != shape:
        raise InvalidAction(f"action of shape {a.shape}; expected {shape}")
    # a . a is finite exactly when every entry is (unless the sum overflows: then check each entry).
    if not (math.isfinite(a.dot(a)) or np.isfinite(a).all()):
        raise InvalidAction(f"action {a} contains NaN or inf; it is rejected before it reaches the simulator")
    return np.minimum(np.maximum(a, low), high)


class TaskEnv(gym.Env, EzPickle):
    """A goal environment built from a task (a built-in name, a TOML file or a Task); docs/tasks.md.

    Args:
        task: "UR5eReach-v0", ... (envs.tasks.BUILTIN_TASKS), a TOML file path, or a Task.
        obs: overrides the task's observation (a preset or task-map spec).
        action: overrides the task's action with a built-in mode (ACTION_PRESETS); the task's
            suction dimension is kept.
        success_radius: overrides the task's position tolerance [m].
        ik_iterations: 1 = the paper's single linearised IK step per control step; more = a local
            iterative solve.
        render_mode: None, "rgb_array" or "human"; width, height: rgb_array image size.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 25}

    def __init__(
        self,
        task: Task | str | Path = "UR5eReach-v0",
        obs: str | None = None,
        action: str | None = None,
        render_mode: str | None = None,
        success_radius: float | None = None,
        ik_iterations: int = 1,
        width: int = 480,
        height: int = 480,
    ):
        EzPickle.__init__(self, task, obs, action, render_mode, success_radius, ik_iterations, width, height)
        task = load_task(task)
        if action is not None and action not in ACTION_PRESETS:
            raise InvalidConfig(f"unknown action mode {action!r}; accepted: {', '.join(ACTION_PRESETS)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidConfig(
                f"unknown render_mode {render_mode!r}; accepted: None, {', '.join(self.metadata['render_modes'])}"
            )
        if success_radius is not None and not success_radius > 0:
            raise InvalidConfig(f"success_radius must be > 0 m; got {success_radius}")
        if ik_iterations < 1:
            raise InvalidConfig(f"ik_iterations must be >= 1; got {ik_iterations}")
        overrides: dict[str, Any] = {}
        if obs is not None:
            overrides["observation"] = obs
        if action is not None:
            overrides["action"] = dataclasses.replace(
                ACTION_PRESETS[action], suction=task.action_spec.suction
            )
        if success_radius is not None:
            overrides["success"] = dataclasses.replace(task.success, position=success_radius)
        self.task: Task = dataclasses.replace(task, **overrides) if overrides else task
        #: The action's name: the built-in mode it is (with or without suction), else "task".
        self.action_mode: str = next(
            (
                name
                for name, preset in ACTION_PRESETS.items()
                if dataclasses.replace(preset, suction=self.task.action_spec.suction) == self.task.action_spec
            ),
            "task",
        )
        task = self.task
        self.obs_spec = OBS_PRESETS.get(task.observation, task.observation)
        self.ik_iterations = ik_iterations
        self.render_mode = render_mode
        self._render_size = (width, height)

        self.model = load_scene(task)
        self.data = mujoco.MjData(self.model)
        self._ik_data = mujoco.MjData(self.model)  # IK workspace: the physics state is never touched by it
        self.n_substeps = round(task.control_dt / self.model.opt.timestep)
        if self.n_substeps < 1 or not math.isclose(
            self.n_substeps * self.model.opt.timestep, task.control_dt
        ):
            raise InvalidConfig(
                f"control_dt {task.control_dt} s is not a multiple of the scene's timestep {self.model.opt.timestep} s"
            )
        self.robot: Robot = load_robot(task.robot_path).validate(self.model)
        joints = self.robot.joints
        if not self.robot.actuators:
            raise InvalidConfig(
                f"robot {self.robot.name!r} has no position servos (actuators); a task needs them"
            )
        self._arm_qpos = as_slice(arm_qpos_indices(self.model, joints))
        self._arm_ctrl = as_slice([name_to_id(self.model, "actuator", n) for n in self.robot.actuators])
        self._joint_range = joint_limits(self.model, joints)
        self.action_map = ActionMap(task.action_spec, self.model, len(joints))
        if task.action_spec.suction and self.robot.suction is None:
            raise InvalidConfig(
                f"the task's action has suction, but robot {self.robot.name!r} has no suction actuator"
            )
        self._suction_ctrl = (
            name_to_id(self.model, "actuator", self.robot.suction) if task.action_spec.suction else None
        )
        self._home_key = name_to_id(self.model, "key", self.robot.home) if self.robot.home else None
        self.plan = StepPlan(self.model, self.obs_spec, task, self.action_map.ik_map, joints)
        self.randomizer = Randomizer(self.model, task, self.robot)
        # One solver: a single step per period, or a local solve (no restarts) of ik_iterations steps.
        # A redundant arm (more than six joints) keeps its elbow near home through the null-space posture.
        posture = tuple(self.robot.home_q(self.model)) if len(joints) > 6 else None
        ik_map = self.action_map.ik_map
        ik_options = IKOptions(max_iters=ik_iterations, restarts=0, posture=posture)
        self._ik = DlsSolver(self.model, ik_map, joints, ik_options) if ik_map else None
        # Live views of data.qpos, data.ctrl and MuJoCo's warning counters (mjNWARNING,).
        self._qpos, self._ctrl = self.data.qpos, self.data.ctrl
        self._warning_counts = self.data.warning.number
        self._steps = 0
        self._success_value, self._failure_value = (1.0, 0.0) if task.success.reward == "0/1" else (0.0, -1.0)

        goal_dim = self.plan.goal_dim
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-np.inf, np.inf, (self.plan.obs_map.dim,), np.float64),
                "achieved_goal": spaces.Box(-np.inf, np.inf, (goal_dim,), np.float64),
                "desired_goal": spaces.Box(-np.inf, np.inf, (goal_dim,), np.float64),
            }
        )
        self.action_space = spaces.Box(-1.0, 1.0, (self.action_map.dim,), np.float32)
        self._action_low = self.action_space.low.astype(np.float64)
        self._action_high = self.action_space.high.astype(np.float64)
        self._renderer = None
        self._viewer = None
        self._check_ik_reaches_home_targets()

    # -- structure -------------------------------------------------------------------------------
    @property
    def obs_map(self):
        """The observation's multi task map (a Stack)."""
        return self.plan.obs_map

    @property
    def observation_structure(self) -> dict[str, slice]:
        """Which slice of `observation` each feature (task-map spec) occupies."""
        return dict(self.plan.obs_map.slices)

    @property
    def goal_structure(self) -> dict[str, slice]:
        """Which slice of `achieved_goal` / `desired_goal` each goal part (and penalty map) occupies."""
        return dict(self.plan.goal_slices)

    # -- Gymnasium API ----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self._reset_to_home(self.data)
        self.randomizer.randomize(self.data, self.np_random)
        mujoco.mj_forward(self.model, self.data)
        self.plan.evaluate(self.model, self.data)
        self._steps = 0
        obs = self._observation()
        return obs, self._info(obs, ik_error=0.0)

    def step(self, action: ArrayLike):
        a = _checked_action(action, self.action_space.shape, self._action_low, self._action_high)
        q_target, ik_error = self._joint_targets(a)
        self._ctrl[self._arm_ctrl] = q_target
        if self._suction_ctrl is not None:
            self._ctrl[self._suction_ctrl] = 1.0 if a[-1] > 0 else 0.0
        warnings_before = self._instability_count()
        mujoco.mj_step(self.model, self.data, nstep=self.n_substeps)
        self._steps += 1
        # MuJoCo warns and resets the state when a non-finite or huge qpos/qvel/qacc appears.
        if self._instability_count() > warnings_before:
            obs = self._last_obs
            info = self._info(obs, ik_error) | {"physics_unstable": True}
            return obs, 0.0, False, True, info
        self.plan.evaluate(self.model, self.data)
        obs = self._observation()
        info = self._info(obs, ik_error)
        reward = self._success_value if info["is_success"] else self._failure_value
        terminated = False
        if self.plan.penalties:
            reward += info["penalty"]
            terminated = info["penalty_terminates"]
        truncated = self._steps >= self.task.episode_steps
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """Paper eq. 8: the success value where every goal part is within its tolerance, else the failure
        value (0/1 by default; 0/-1 with reward = "-1/0"), plus the penalties on the achieved goal.

        Reads only the goals. Vectorised: goals (g,) -> (), (B, g) -> (B,); float32.
        """
        achieved, desired = np.asarray(achieved_goal), np.asarray(desired_goal)
        success = self.plan.is_success(achieved, desired)
        reward = np.where(success, self._success_value, self._failure_value)
        for cols, penalty in self.plan.penalties:
            value = achieved[..., cols]
            applies = value < penalty.above if penalty.below else value > penalty.above
            reward = reward + np.where(applies, penalty.reward, 0.0)
        return reward.astype(np.float32)

    def relabel(self, obs: dict[str, np.ndarray], new_goal: ArrayLike) -> dict[str, np.ndarray]:
        """The observation the environment would have emitted with the target moved to `new_goal`.

        Goal-dependent features (position(target), positionDiff(tcp, target), quaternionDiff(tcp,
        target), ...) are recomputed; the rest is unchanged. `obs` arrays are (d,) or batched (B, d);
        `new_goal` (g,) or (B, g); its penalty columns are replaced by their desired value 0.
        """
        desired = np.asarray(obs["desired_goal"], dtype=np.float64)
        goal = np.broadcast_to(np.asarray(new_goal, dtype=np.float64), desired.shape)
        move = self.plan.target_move(np.asarray(obs["achieved_goal"], np.float64), desired, goal)
        observation = relabelled(self.plan.obs_map, np.asarray(obs["observation"], np.float64), move)
        desired_goal = goal.copy()
        for cols, _ in self.plan.penalties:
            desired_goal[..., cols] = 0.0
        return {
            "observation": observation,
            "achieved_goal": np.array(obs["achieved_goal"], dtype=np.float64),
            "desired_goal": desired_goal,
        }

    def move_target(self, goal: ArrayLike) -> dict[str, np.ndarray]:
        """Moves the goal marker to the goal `goal` (g,) without stepping physics; returns the new observation."""
        goal = np.asarray(goal, dtype=np.float64)
        self.randomizer.place_target(self.data, goal[:3], goal[3:7] if self.plan.pose_goal else None)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        self.plan.evaluate(self.model, self.data)
        return self._observation()

    def render(self):
        if self.render_mode == "rgb_array":
            from ..rendering import SceneRenderer

            if self._renderer is None:
                self._renderer = SceneRenderer(self.model, *self._render_size)
            return self._renderer.render(self.data)
        if self.render_mode == "human":
            if self._viewer is None:
                if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
                    raise InvalidConfig("render_mode='human' needs a display; use render_mode='rgb_array'")
                import mujoco.viewer

                self._viewer = mujoco.viewer.launch_passive(self.model, self.data)
            self._viewer.sync()
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    # -- internals ---------------------------------------------------------------------------------
    def _observation(self) -> dict[str, np.ndarray]:
        observation, achieved, desired = self.plan.views
        obs = {
            "observation": observation.copy(),
            "achieved_goal": achieved.copy(),
            "desired_goal": desired.copy(),
        }
        self._last_obs = obs
        return obs

    def _info(self, obs: dict[str, np.ndarray], ik_error: float) -> dict[str, Any]:
        return self.plan.info(obs["achieved_goal"], obs["desired_goal"]) | {"ik_error": float(ik_error)}

    def _reset_to_home(self, data: mujoco.MjData) -> None:
        """The home keyframe (the model's default state where the robot names none), at rest."""
        if self._home_key is None:
            mujoco.mj_resetData(self.model, data)
        else:
            mujoco.mj_resetDataKeyframe(self.model, data, self._home_key)

    def _instability_count(self) -> int:
        counts = self._warning_counts.tolist()
        return counts[_BADQACC] + counts[_BADQVEL] + counts[_BADQPOS]

    def _joint_targets(self, a: np.ndarray) -> tuple[np.ndarray, float]:
        """Servo targets (n,) for action `a`, and the IK residual (0 for joint actions)."""
        if self._ik is None:
            q = self._qpos[self._arm_qpos]
            n = len(q)
            step = self.action_map.spec.joint_step
            return np.minimum(
                np.maximum(q + step * a[:n], self._joint_range[:, 0]), self._joint_range[:, 1]
            ), 0.0
        initial = self.plan.ik_value
        target = self.action_map.ik_target(a, initial.y)
        if self.ik_iterations == 1:  # the paper's single linearised step, on this step's Jacobian
            # Its inputs come from the step's own maps and state (finite: a blow-up ends the episode).
            return self._ik.step(self._qpos[self._arm_qpos], initial, target)
        self._ik_data.qpos[:] = self.data.qpos
        result = self._ik.solve(self._ik_data, target, initial)  # a local solve from the current pose
        return result.q, result.error_norm

    def _check_ik_reaches_home_targets(self) -> None:
        """The IK must meet the held values from home (catches conflicting held maps, e.g. two axes)."""
        hold = self.action_map.spec.hold
        if not hold or self.action_map.ik_map is None:
            return
        held = Stack(self.action_map.ik_map.parts[len(self.action_map.spec.parts) :])
        target = np.concatenate([h.value for h in hold])
        data = self._ik_data
        self._reset_to_home(data)
        mujoco.mj_kinematics(self.model, data)
        mujoco.mj_comPos(self.model, data)
        result = DlsSolver(self.model, held, self.robot.joints).solve(data, target)
        if not result.converged:
            raise InvalidConfig(
                f"the IK cannot hold {held.spec} at {target.round(3).tolist()} (residual {result.error_norm:.3g} "
                "from home): conflicting or unreachable held values"
            )
