"""TsrlGoalEnv: the goal-conditioned MuJoCo environment shared by the UR5e reach and pick-and-place tasks.

One step: action -> desired task-map values -> IK -> servo targets -> physics substeps -> the task maps
evaluated once, their values and Jacobians reused for observation, reward and the next step's IK.
"""

from __future__ import annotations

import math
import os
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces
from gymnasium.utils import EzPickle
from numpy.typing import ArrayLike

from ..assets import load_model
from ..assets.ur5e import HOME_KEY, JOINT_LIMITS, JOINT_NAMES, SUCTION_ACTUATOR, TARGET_BODY, TARGET_SITE
from ..exceptions import InvalidAction, InvalidConfig
from ..ik import DlsSolver, IKOptions
from ..kinematics import arm_qpos_indices, as_slice, name_to_id
from ..taskmaps import OBS_PRESETS, Stack, TaskMapValue, parse_spec
from .actions import ACTION_MODES, ActionConfig

#: Target of vectorZ(tcp) in `taskspace` mode: the suction cup points down.
_CUP_DOWN = np.array([0.0, 0.0, -1.0])

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


class TsrlGoalEnv(gym.Env, EzPickle):
    """Base class; subclasses set the scene, the achieved-goal map and the randomisation."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["human", "rgb_array"], "render_fps": 25}

    #: Built-in scene (tsrl.assets.SCENES).
    scene: str
    #: Task map whose value is the achieved goal (3,).
    achieved_goal_spec: str
    #: Whether the action has a suction dimension.
    has_suction: bool = False
    #: Control period [s] (25 Hz) and number of 2 ms physics substeps per control period.
    control_dt: float = 0.04
    #: Bounds [m] of the TCP position target: above the table and within reach.
    workspace_low = np.array([-0.9, -0.55, 0.02])
    workspace_high = np.array([-0.15, 0.3, 0.7])

    def __init__(
        self,
        obs: str = "baseline",
        action: str = "taskspace",
        render_mode: str | None = None,
        success_radius: float = 0.05,
        ik_iterations: int = 1,
        width: int = 480,
        height: int = 480,
    ):
        EzPickle.__init__(self, obs, action, render_mode, success_radius, ik_iterations, width, height)
        if action not in ACTION_MODES:
            raise InvalidConfig(f"unknown action mode {action!r}; accepted: {', '.join(ACTION_MODES)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise InvalidConfig(
                f"unknown render_mode {render_mode!r}; accepted: None, {', '.join(self.metadata['render_modes'])}"
            )
        if not success_radius > 0:
            raise InvalidConfig(f"success_radius must be > 0 m; got {success_radius}")
        if ik_iterations < 1:
            raise InvalidConfig(f"ik_iterations must be >= 1; got {ik_iterations}")
        self.obs_spec = OBS_PRESETS.get(obs, obs)
        self.action_config = ActionConfig(mode=action, suction=self.has_suction)
        self.success_radius = success_radius
        self.ik_iterations = ik_iterations
        self.render_mode = render_mode
        self._render_size = (width, height)

        self.model = load_model(self.scene)
        self.data = mujoco.MjData(self.model)
        self._ik_data = mujoco.MjData(self.model)  # IK workspace: the physics state is never touched by it
        self.n_substeps = round(self.control_dt / self.model.opt.timestep)
        self._arm_qpos = as_slice(arm_qpos_indices(self.model))
        self._arm_ctrl = as_slice([name_to_id(self.model, "actuator", n) for n in JOINT_NAMES])
        self._suction_ctrl = (
            name_to_id(self.model, "actuator", SUCTION_ACTUATOR) if self.has_suction else None
        )
        self._target_mocap = self.model.body_mocapid[name_to_id(self.model, "body", TARGET_BODY)]
        self._home_key = name_to_id(self.model, "key", HOME_KEY)

        self.obs_map = parse_spec(self.obs_spec, self.model)
        ik_spec = self.action_config.ik_spec
        self.ik_map = parse_spec(ik_spec, self.model) if ik_spec else None
        # One solver: a single step per period, or a local solve (no restarts) of ik_iterations steps.
        ik_options = IKOptions(max_iters=ik_iterations, restarts=0)
        self._ik = DlsSolver(self.model, self.ik_map, JOINT_NAMES, ik_options) if ik_spec else None
        # Every map a step needs, in one stack evaluated once per step: the observation's maps, then
        # those of the IK and the goals that the observation lacks (a map already there is read there).
        achieved, desired = parse_spec(
            f"{self.achieved_goal_spec}, position({TARGET_SITE})", self.model
        ).parts
        step_parts = list(self.obs_map.parts)
        for part in (*(self.ik_map.parts if self.ik_map else ()), achieved, desired):
            if all(part.spec != p.spec for p in step_parts):
                step_parts.append(part)
        self._step_maps = Stack(step_parts)
        rows = self._step_maps.slices  # a spec's first occurrence is keyed by the spec itself
        self._achieved_rows, self._desired_rows = rows[achieved.spec], rows[desired.spec]
        # The IK map's rows: a slice where they follow one another in the stack, else gathered each step.
        self._ik_rows: slice | np.ndarray | None = None
        if self.ik_map is not None:
            self._ik_rows = as_slice(
                [i for p in self.ik_map.parts for i in range(rows[p.spec].start, rows[p.spec].stop)]
            )
        # Set by _evaluate: the stack's output buffers and views of their rows (observation, achieved
        # and desired goal; the IK map's value, or buffers it is gathered into).
        self._value: TaskMapValue | None = None
        self._views: tuple[np.ndarray, np.ndarray, np.ndarray] = ()
        self._ik_value: TaskMapValue | None = None
        # The IK's target, rewritten each step; in taskspace mode only its position part changes.
        self._ik_target = np.zeros(self.ik_map.dim) if ik_spec else None
        if self.action_config.mode == "taskspace":
            self._ik_target[3:] = _CUP_DOWN
        # Live views of data.qpos, data.ctrl and MuJoCo's warning counters (mjNWARNING,).
        self._qpos, self._ctrl = self.data.qpos, self.data.ctrl
        self._warning_counts = self.data.warning.number

        self.observation_space = spaces.Dict(
            {
                "observation": spaces.Box(-np.inf, np.inf, (self.obs_map.dim,), np.float64),
                "achieved_goal": spaces.Box(-np.inf, np.inf, (3,), np.float64),
                "desired_goal": spaces.Box(-np.inf, np.inf, (3,), np.float64),
            }
        )
        self.action_space = spaces.Box(-1.0, 1.0, (self.action_config.dim,), np.float32)
        self._action_low = self.action_space.low.astype(np.float64)
        self._action_high = self.action_space.high.astype(np.float64)
        self._renderer = None
        self._viewer = None

    # -- structure -------------------------------------------------------------------------------
    @property
    def observation_structure(self) -> dict[str, slice]:
        """Which slice of `observation` each feature (task-map spec) occupies."""
        return dict(self.obs_map.slices)

    # -- Gymnasium API ----------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        mujoco.mj_resetDataKeyframe(self.model, self.data, self._home_key)
        self._randomize()
        mujoco.mj_forward(self.model, self.data)
        self._evaluate()
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
        # MuJoCo warns and resets the state when a non-finite or huge qpos/qvel/qacc appears.
        if self._instability_count() > warnings_before:
            obs = self._last_obs
            info = self._info(obs, ik_error) | {"physics_unstable": True}
            return obs, 0.0, False, True, info
        self._evaluate()
        obs = self._observation()
        info = self._info(obs, ik_error)
        reward = 1.0 if info["is_success"] else 0.0  # compute_reward's rule, on the distance _info has
        if self.render_mode == "human":
            self.render()
        return obs, reward, False, False, info

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray, info: Any) -> np.ndarray:
        """1 where ||achieved - desired|| < success_radius, else 0 (paper eq. 8; Gymnasium-Robotics uses 0/-1).

        Reads only the goals. Vectorised: goals (3,) -> (), (B, 3) -> (B,); float32.
        """
        diff = np.asarray(achieved_goal) - np.asarray(desired_goal)
        return (np.einsum("...i,...i->...", diff, diff) < self.success_radius**2).astype(np.float32)

    def relabel(self, obs: dict[str, np.ndarray], new_goal: ArrayLike) -> dict[str, np.ndarray]:
        """The observation the environment would have emitted with the goal at `new_goal`.

        Goal-dependent features (position(target), positionDiff(tcp, target), ...) are recomputed;
        the rest is unchanged. `obs` arrays are (d,) or batched (B, d); `new_goal` (3,) or (B, 3).
        """
        desired = np.asarray(obs["desired_goal"], dtype=np.float64)
        goal = np.broadcast_to(np.asarray(new_goal, dtype=np.float64), desired.shape)
        observation = self.obs_map.translated(
            np.asarray(obs["observation"], np.float64), TARGET_SITE, goal - desired
        )
        return {
            "observation": np.asarray(observation, dtype=np.float64),
            "achieved_goal": np.array(obs["achieved_goal"], dtype=np.float64),
            "desired_goal": goal.copy(),
        }

    def move_target(self, goal: ArrayLike) -> dict[str, np.ndarray]:
        """Moves the goal marker to `goal` (3,) without stepping physics; returns the new observation."""
        self.data.mocap_pos[self._target_mocap] = np.asarray(goal, dtype=np.float64)
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_comPos(self.model, self.data)
        self._evaluate(kinematics=False)
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
    def _randomize(self) -> None:
        """Samples the goal (and objects) with self.np_random; sets them in self.data."""
        raise NotImplementedError

    def _evaluate(self, kinematics: bool = True) -> None:
        """Evaluates every map of the step once at the current state (after the physics substeps)."""
        if kinematics:
            mujoco.mj_kinematics(self.model, self.data)
            mujoco.mj_comPos(self.model, self.data)
        value = self._step_maps.in_place(self.model, self.data)
        if value is not self._value:  # the stack's buffers, the same from the first call on: view them once
            self._value = value
            y, J = value
            self._views = (y[: self.obs_map.dim], y[self._achieved_rows], y[self._desired_rows])
            ik = self._ik_rows
            if isinstance(ik, slice):
                self._ik_value = TaskMapValue(y[ik], J[ik])
            elif ik is not None:
                self._ik_value = TaskMapValue(np.empty(ik.size), np.empty((ik.size, J.shape[1])))
        if isinstance(self._ik_rows, np.ndarray):  # gather the IK map's rows
            np.take(value.y, self._ik_rows, out=self._ik_value.y)
            np.take(value.J, self._ik_rows, axis=0, out=self._ik_value.J)

    def _observation(self) -> dict[str, np.ndarray]:
        observation, achieved, desired = self._views
        obs = {
            "observation": observation.copy(),
            "achieved_goal": achieved.copy(),
            "desired_goal": desired.copy(),
        }
        self._last_obs = obs
        return obs

    def _info(self, obs: dict[str, np.ndarray], ik_error: float) -> dict[str, Any]:
        diff = obs["achieved_goal"] - obs["desired_goal"]
        squared = diff.dot(diff)
        return {
            "is_success": bool(squared < self.success_radius**2),  # as in compute_reward
            "distance": math.sqrt(squared),
            "ik_error": float(ik_error),
        }

    def _instability_count(self) -> int:
        counts = self._warning_counts.tolist()
        return counts[_BADQACC] + counts[_BADQVEL] + counts[_BADQPOS]

    def _joint_targets(self, a: np.ndarray) -> tuple[np.ndarray, float]:
        """Servo targets (6,) for action `a`, and the IK residual (0 for joint actions)."""
        cfg = self.action_config
        if cfg.mode == "joint":
            q = self._qpos[self._arm_qpos]
            return np.minimum(
                np.maximum(q + cfg.max_joint_step * a[:6], JOINT_LIMITS[:, 0]), JOINT_LIMITS[:, 1]
            ), 0.0
        initial = self._ik_value
        # The TCP position target y + step * a within the workspace; in taskspace mode the rest of
        # the target (cup down) is constant.
        p = self._ik_target[:3]
        np.multiply(a[:3], cfg.max_tcp_step, out=p)
        np.add(initial.y[:3], p, out=p)
        np.minimum(np.maximum(p, self.workspace_low, out=p), self.workspace_high, out=p)
        if cfg.mode == "taskspace_orient":
            self._ik_target[3:] = a[3:6]
        target = self._ik_target
        if self.ik_iterations == 1:  # the paper's single linearised step, on this step's Jacobian
            # Its inputs come from the step's own maps and state (finite: a blow-up ends the episode).
            return self._ik.step(self._qpos[self._arm_qpos], initial, target)
        self._ik_data.qpos[:] = self.data.qpos
        result = self._ik.solve(self._ik_data, target, initial)  # a local solve from the current pose
        return result.q, result.error_norm
