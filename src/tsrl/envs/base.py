"""TaskEnv: the one goal-conditioned MuJoCo environment that builds any task (envs/tasks.py).

One step (the Gymnasium-Robotics skeleton): check the action, the task-space interface
(envs/interface.py, the deployment controller's too) turns it into servo targets and the tool
command (action map, IK), physics substeps, the interface's task maps evaluated once (their values
and Jacobians reused for observation, goals, reward and the next step's IK), `compute_reward`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from numpy.typing import ArrayLike

from ..exceptions import InvalidAction, InvalidConfig, TsrlError
from ..robots import Robot, load_robot
from ..taskmaps import Stack, resolve_frame
from .actions import action_mode
from .interface import TaskInterface
from .observations import OBS_PRESETS, PREVIOUS_ACTIONS
from .perturbations import Perturber
from .randomization import Randomizer
from .scenes import load_scene
from .tasks import Task, load_task

#: The MuJoCo part of what `TaskEnv.get_state` gives and `restore_state` takes (mj_getState's spec).
STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION

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
        reward_scale: overrides the task's reward scale (SuccessSpec.reward_scale: the reward counts
            success within this fraction of the tolerances; is_success stays at the tolerances).
        ik_iterations: 1 = the paper's single linearised IK step per control step; more = a local
            iterative solve.
        render_mode: None, "rgb_array" or "human"; width, height: rgb_array image size.
        camera: the name of a camera in the model for rgb_array images; None: a camera aimed at the
            task's workspace (the goal box and the TCP at home, seen from beside the robot's base).
    """

    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 25}  # noqa: RUF012 (Gymnasium's)

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
        camera: str | None = None,
        reward_scale: float | None = None,
    ):
        EzPickle.__init__(
            self, task, obs, action, render_mode, success_radius, ik_iterations, width, height, camera,
            reward_scale,
        )  # fmt: skip
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidConfig(
                f"unknown render_mode {render_mode!r}; accepted: None, {', '.join(self.metadata['render_modes'])}"
            )
        if isinstance(ik_iterations, bool) or not isinstance(ik_iterations, int) or ik_iterations < 1:
            raise InvalidConfig(f"ik_iterations must be an integer >= 1; got {ik_iterations!r}")
        self.task: Task = load_task(task).with_overrides(obs, action, success_radius, reward_scale)
        #: The action's name: the built-in mode it is (with or without suction), else "task".
        self.action_mode: str = action_mode(self.task.action_spec)
        self.obs_spec: str = OBS_PRESETS.get(self.task.observation, self.task.observation)
        self.ik_iterations = ik_iterations
        self.render_mode = render_mode
        self._render_size = (width, height)
        self._renderer: Any = None
        self._camera = camera
        self._viewer: Any = None
        with _named_source(self.task):
            self._build()

    def _build(self) -> None:
        """The model and everything bound to it: robot, action map, goal, step plan, randomizer, IK."""
        task = self.task
        self.model = load_scene(task)
        self.data = mujoco.MjData(self.model)
        self.n_substeps = round(task.control_dt / self.model.opt.timestep)
        if self.n_substeps < 1 or not math.isclose(
            self.n_substeps * self.model.opt.timestep, task.control_dt
        ):
            raise InvalidConfig(
                f"control_dt = {task.control_dt} s is not a multiple of the scene's timestep "
                f"{self.model.opt.timestep} s"
            )
        self.bound_robot = load_robot(task.robot_path).bind(self.model)
        self.robot: Robot = self.bound_robot.robot
        #: The task-space interface: step plan, action map and tool, previous actions, IK.
        self.interface = TaskInterface(task, self.model, self.bound_robot, self.obs_spec, self.ik_iterations)
        self.action_map = self.interface.action_map
        self.goal = self.interface.goal
        self.plan = self.interface.plan
        self.ik_options = self.interface.ik_options
        self.randomizer = Randomizer(self.model, task, self.bound_robot, self.goal)
        self._perturb = (
            Perturber(self.model, task, self.bound_robot, self.goal, self.plan.obs_map, self.n_substeps)
            if task.randomize.active
            else None
        )
        # Live views of data.qpos, data.ctrl and MuJoCo's warning counters (mjNWARNING,).
        self._qpos, self._ctrl = self.data.qpos, self.data.ctrl
        self._warning_counts = self.data.warning.number
        self._steps = 0
        self._previous_actions = self.interface.previous_actions  # (n, k), newest first
        self._tool_ctrl = self.interface.tool_ctrl
        #: Rows of the "observation" entry: the observation map's, then the previous actions'.
        self.obs_dim: int = self.interface.obs_dim
        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-np.inf, np.inf, (self.obs_dim,), np.float64),
                "achieved_goal": spaces.Box(-np.inf, np.inf, (self.goal.dim,), np.float64),
                "desired_goal": spaces.Box(-np.inf, np.inf, (self.goal.dim,), np.float64),
            }
        )
        self._action_shape = (self.action_map.dim,)
        self.action_space = spaces.Box(-1.0, 1.0, self._action_shape, np.float32)
        self._action_low = self.action_space.low.astype(np.float64)
        self._action_high = self.action_space.high.astype(np.float64)

    # -- structure -------------------------------------------------------------------------------
    @property
    def obs_map(self) -> Stack:
        """The observation's multi task map."""
        return self.plan.obs_map

    @property
    def observation_structure(self) -> dict[str, slice]:
        """Which slice of `observation` each feature (task-map spec, or `previous_actions`) occupies."""
        slices = dict(self.plan.obs_map.slices)
        if self._previous_actions.size:
            dim = self.plan.obs_map.dim
            slices[PREVIOUS_ACTIONS] = slice(dim, dim + self._previous_actions.size)
        return slices

    @property
    def goal_structure(self) -> dict[str, slice]:
        """Which slice of `achieved_goal` / `desired_goal` each goal part (and penalty map) occupies."""
        return dict(self.goal.slices)

    # -- Gymnasium API ----------------------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        super().reset(seed=seed)
        self.bound_robot.reset_to_home(self.model, self.data)
        self.randomizer.randomize(self.data, self.np_random)
        if self._perturb is not None:
            self._perturb.episode(self.data, self.np_random, self.action_map.dim)
            self._perturb.draw_noise(self.np_random)
        mujoco.mj_forward(self.model, self.data)
        self.plan.evaluate(self.model, self.data)
        self._steps = 0
        self.interface.reset()
        obs = self._observation()
        _, info = self.goal.outcome(obs["achieved_goal"], obs["desired_goal"])
        info["ik_error"] = 0.0
        if self._perturb is not None and self._perturb.spec.goal_offset > 0:
            info |= self._perturb.true_info(obs["achieved_goal"], obs["desired_goal"])
        return obs, info

    def step(self, action: ArrayLike) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        a = _checked_action(action, self._action_shape, self._action_low, self._action_high)
        interface = self.interface
        interface.remember(a)
        perturb = self._perturb
        if perturb is not None:
            a = perturb.delayed(a)
        q_target, ik_error, _, tool = interface.command(a, self._qpos[self.bound_robot.qpos], self.data)
        self._ctrl[self.bound_robot.ctrl] = q_target
        if tool is not None:
            self._ctrl[self._tool_ctrl] = tool
        warnings_before = self._instability_count()
        substeps = self.n_substeps if perturb is None else perturb.substeps(self.np_random)
        mujoco.mj_step(self.model, self.data, nstep=substeps)
        self._steps += 1
        # MuJoCo warns and resets the state when a non-finite or huge qpos/qvel/qacc appears: the step
        # then ends the episode (truncated) with the last observation, its reward and info.
        unstable = self._instability_count() > warnings_before
        if not unstable:
            self.plan.evaluate(self.model, self.data)
        if perturb is not None:
            perturb.draw_noise(self.np_random)
        obs = self._observation()
        reward, info = self.goal.outcome(obs["achieved_goal"], obs["desired_goal"])
        info["ik_error"] = float(ik_error)
        if perturb is not None and perturb.spec.goal_offset > 0:
            info |= perturb.true_info(obs["achieved_goal"], obs["desired_goal"])
        if unstable:
            info["physics_unstable"] = True
            return obs, reward, False, True, info
        terminated = bool(info.get("penalty_terminates", False))
        truncated = self._steps >= self.task.episode_steps
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """The step's reward of these goals (`Goal.reward`: eq. 8's success or failure value, 0/1 or
        -1/0, plus the penalties on the achieved goal). Reads only the goals.

        Vectorised: goals (g,) -> (), (B, g) -> (B,); float32.
        """
        return self.goal.reward(np.asarray(achieved_goal), np.asarray(desired_goal)).astype(np.float32)

    def relabel(self, obs: dict[str, np.ndarray], new_goal: ArrayLike) -> dict[str, np.ndarray]:
        """The observation the environment would have emitted with the markers moved to `new_goal`.

        Goal-dependent features (position(target), positionDiff(tcp, target), quaternionDiff(tcp,
        target), ...) are recomputed; the rest is unchanged. `obs` arrays are (d,) or batched (B, d);
        `new_goal` (g,) or (B, g); its penalty columns are replaced by their desired value 0.
        """
        return self.goal.relabel(self.plan.obs_map, obs, new_goal)

    def get_state(self) -> np.ndarray:
        """The state restore_state takes, float64 (mj_stateSize + previous_actions x action dim,): MuJoCo's
        integration state (mj_getState with mjSTATE_INTEGRATION: time, qpos, qvel, act, warm start,
        ctrl, mocap poses, ...) followed by the policy's previous actions (`Task.previous_actions`,
        newest first; nothing where the task observes none)."""
        physics = np.empty(mujoco.mj_stateSize(self.model, STATE_SPEC))
        mujoco.mj_getState(self.model, self.data, physics, STATE_SPEC)
        return np.concatenate([physics, self._previous_actions.ravel()])

    def restore_state(self, state: np.ndarray) -> dict[str, np.ndarray]:
        """Writes a state from get_state into the simulation and the previous actions and returns its
        observation, e.g. a demonstration's state to start an episode from (Nair et al. 2018's
        resets)."""
        state = np.asarray(state, dtype=np.float64)
        n_physics = mujoco.mj_stateSize(self.model, STATE_SPEC)
        if state.shape != (n_physics + self._previous_actions.size,):
            raise ValueError(
                f"restore_state: a state of task {self.task.name!r} has shape "
                f"({n_physics + self._previous_actions.size},) (get_state's); got {state.shape}"
            )
        mujoco.mj_setState(self.model, self.data, state[:n_physics], STATE_SPEC)
        self._previous_actions[:] = state[n_physics:].reshape(self._previous_actions.shape)
        mujoco.mj_forward(self.model, self.data)
        self.plan.evaluate(self.model, self.data)
        return self._observation()

    def move_target(self, goal: ArrayLike) -> dict[str, np.ndarray]:
        """Moves the goal markers to the goal `goal` (g,) without stepping physics; returns the new observation."""
        self.goal.place(self.data, np.asarray(goal, dtype=np.float64))
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        self.plan.evaluate(self.model, self.data)
        return self._observation()

    def render(self) -> np.ndarray | None:
        if self.render_mode == "rgb_array":
            from ..rendering import SceneRenderer

            if self._renderer is None:
                self._renderer = SceneRenderer(self.model, *self._render_size, camera=self._camera_view())
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
    def _camera_view(self) -> Any:
        """The named camera, or a free camera framing the goal box and the TCP at home from the base."""
        from ..rendering import named_camera, workspace_camera

        if self._camera is not None:
            return named_camera(self.model, self._camera)
        p = self.task.goal.position
        center = np.array(p.center) + [0.0, 0.0, p.max_lift / 2]
        half = np.array(p.half_extent) + [0.0, 0.0, p.max_lift / 2]
        corners = center + half * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        data = mujoco.MjData(self.model)
        self.bound_robot.reset_to_home(self.model, data)
        mujoco.mj_kinematics(self.model, data)
        tcp, base = (_frame_position(self.model, data, name) for name in ("tcp", "base"))
        return workspace_camera(self.model, np.vstack([corners, tcp]), base)

    def _observation(self) -> dict[str, np.ndarray]:
        """Fresh copies of the last evaluation's observation (with this step's noise, then the previous
        actions) and goals."""
        observation, achieved, desired = self.plan.views
        if self._perturb is not None:
            observation = observation + self._perturb.noise
        return {
            "observation": np.concatenate([observation, self._previous_actions.ravel()])
            if self._previous_actions.size
            else observation.copy(),
            "achieved_goal": achieved.copy(),
            "desired_goal": desired.copy(),
        }

    def _instability_count(self) -> int:
        counts = self._warning_counts.tolist()
        return counts[_BADQACC] + counts[_BADQVEL] + counts[_BADQPOS]


@contextmanager
def _named_source(task: Task) -> Iterator[None]:
    """Errors raised while a task is built on its model name the task's file first."""
    try:
        yield
    except TsrlError as err:
        if task.source is None or str(err).startswith(str(task.source)):
            raise
        raise _with_prefix(err, f"{task.source}: ") from None


def _with_prefix(err: TsrlError, prefix: str) -> TsrlError:
    """A copy of `err` (same class) whose message starts with `prefix`."""
    new = Exception.__new__(type(err))
    new.args = (prefix + str(err),)
    return new


def _frame_position(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """World position (3,) of the site, else body, called `name` (kinematics done)."""
    frame = resolve_frame(model, name)
    return data.site_xpos[frame.id] if frame.kind == "site" else data.xpos[frame.id]
