"""Observation presets and the step plan: every task map a step needs, in one stack evaluated once,
with named rows.

Rows of the stack: the observation's maps first (so `observation` is its leading rows), then the
maps of the IK, the achieved and desired goal and the penalties that the observation lacks (a map
already there is read there). Goals and the IK read their rows as views where the rows follow one
another, and gather them into buffers where they do not.
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..kinematics import as_slice
from ..taskmaps import Position, Quaternion, Stack, TaskMap, TaskMapValue, Velocity, parse_spec
from ..taskmaps.relabel import FrameMove, FramePose, check_relabelable
from .scenes import TARGET_SITE
from .tasks import Penalty, Task

#: Named observation specs: the paper's configurations (Table I) for reach, and its pick-and-place
#: observation. A task's `observation` (or the env's `obs=`) may name them, alone or inside a spec.
OBS_PRESETS: dict[str, str] = {
    "baseline": "position(tcp), velocity(position(tcp))",
    "simple": "positionDiff(tcp, target), velocity(positionDiff(tcp, target))",
    "fs0": "position(tcp), position(target), positionDiff(tcp, target)",
    "fs1": "fs0, velocity(position(tcp)), velocity(positionDiff(tcp, target))",
    "fs2": "fs1, quaternion(tcp), quaternionDiff(tcp, target)",
    # The paper's pick-and-place features phi_1..phi_6: object position, goal position, end-effector
    # position and quaternion, object-goal and end-effector-goal differences (19 values).
    "pick_phi": (
        "position(box), position(target), position(tcp), quaternion(tcp), positionDiff(box, target), "
        "positionDiff(tcp, target)"
    ),
    # pick_phi plus the box relative to the TCP, the box's velocity and the suction cup's state (on,
    # holding) (27 values).
    "pick_phi_plus": "pick_phi, positionDiff(box, tcp), velocity(position(box)), suction(suction)",
}


def parse_observation(spec: str, model: mujoco.MjModel, joints: tuple[str, ...] | None = None) -> Stack:
    """The observation's Stack of a spec that may name OBS_PRESETS (tsrl.taskmaps.parse_spec)."""
    return parse_spec(spec, model, joints, OBS_PRESETS)


class _Rows:
    """Rows of the step stack read as one vector: a view where they are consecutive, else gathered."""

    def __init__(self, rows: list[int], width: int):
        self.index = as_slice(rows)
        self.n = len(rows)
        self.width = width  # >= n: extra columns stay 0 (the desired value of penalty maps)

    def bind(self, y: np.ndarray, J: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        if isinstance(self.index, slice) and self.width == self.n:
            return y[self.index], (J[self.index] if J is not None else None)
        return np.zeros(self.width), (np.empty((self.n, J.shape[1])) if J is not None else None)

    def gather(
        self, y: np.ndarray, out: np.ndarray, J: np.ndarray | None = None, J_out: np.ndarray | None = None
    ) -> None:
        """Copies the rows into the buffers `bind` made (nothing to do for views)."""
        if isinstance(self.index, slice):
            if self.width != self.n:
                out[: self.n] = y[self.index]
                if J is not None:
                    J_out[:] = J[self.index]
            return
        np.take(y, self.index, out=out[: self.n])
        if J is not None:
            np.take(J, self.index, axis=0, out=J_out)


class StepPlan:
    """The maps of one step (observation, goals, penalties, IK) and the rules on goals (success, info).

    Attributes:
        obs_map: the observation's Stack; goal_dim: size of achieved and desired goal vectors;
        goal_slices: each goal part's and penalty map's columns in the goal vectors;
        penalties: (column, Penalty) per penalty map; pose_goal: whether the goal has an orientation.
    """

    def __init__(
        self, model: mujoco.MjModel, obs_spec: str, task: Task, ik_map: Stack | None, joints: tuple[str, ...]
    ):
        self.obs_map = parse_observation(obs_spec, model, joints)
        achieved = parse_spec(task.goal.map, model, joints)
        self.goal_frame = _goal_frame(achieved, task.goal.map)
        self.pose_goal = len(achieved.parts) == 2
        if self.pose_goal and task.goal.orientation is None:
            raise InvalidConfig(f"goal.map {task.goal.map!r} has an orientation: give [goal.orientation]")
        if not self.pose_goal and task.goal.orientation is not None:
            raise InvalidConfig('[goal.orientation] needs a pose goal: map = "position(f), quaternion(f)"')
        desired_spec = f"position({TARGET_SITE})" + (f", quaternion({TARGET_SITE})" if self.pose_goal else "")
        desired = parse_spec(desired_spec, model)
        penalty_maps = [_penalty_map(p, model, joints) for p in task.success.penalties]
        self.success = task.success
        self._cos_half_tolerance = math.cos(math.radians(task.success.orientation) / 2)

        step_parts = list(self.obs_map.parts)
        for part in (*(ik_map.parts if ik_map else ()), *achieved.parts, *desired.parts, *penalty_maps):
            if all(part.spec != p.spec for p in step_parts):
                step_parts.append(part)
        self._maps = Stack(step_parts)
        rows = self._maps.slices  # a spec's first occurrence is keyed by the spec itself

        def rows_of(maps: list[TaskMap]) -> list[int]:
            return [i for m in maps for i in range(rows[m.spec].start, rows[m.spec].stop)]

        goal_maps = [*achieved.parts, *penalty_maps]
        self.goal_dim = sum(m.dim for m in goal_maps)
        self._achieved = _Rows(rows_of(goal_maps), self.goal_dim)
        self._desired = _Rows(rows_of(list(desired.parts)), self.goal_dim)
        self._ik = _Rows(rows_of(list(ik_map.parts)), ik_map.dim) if ik_map else None
        self.goal_slices: dict[str, slice] = {}
        col = 0
        for m in goal_maps:
            self.goal_slices[m.spec] = slice(col, col + m.dim)
            col += m.dim
        self.penalties = [
            (self.goal_slices[m.spec].start, p) for m, p in zip(penalty_maps, task.success.penalties)
        ]
        self._simple = not self.pose_goal and not self.penalties  # goal = one position: the fast rules
        target_body = model.site_bodyid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, TARGET_SITE)]
        self.target_quat = model.body_quat[target_body].copy()  # the target's orientation in the scene
        check_relabelable(self.obs_map, self._trial_move())

        self._value: TaskMapValue | None = None
        self.views: tuple[np.ndarray, np.ndarray, np.ndarray] = ()
        self.ik_value: TaskMapValue | None = None

    # -- evaluation ----------------------------------------------------------------------------------
    def evaluate(self, model: mujoco.MjModel, data: mujoco.MjData, kinematics: bool = True) -> None:
        """Evaluates every map of the step once at the current state (after the physics substeps)."""
        if kinematics:
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
        value = self._maps.in_place(model, data)
        y, J = value
        if value is not self._value:  # the stack's buffers, the same from the first call on: view them once
            self._value = value
            self.views = (y[: self.obs_map.dim], self._achieved.bind(y)[0], self._desired.bind(y)[0])
            if self._ik is not None:
                self.ik_value = TaskMapValue(*self._ik.bind(y, J))
        self._achieved.gather(y, self.views[1])
        self._desired.gather(y, self.views[2])
        if self._ik is not None:
            self._ik.gather(y, self.ik_value.y, J, self.ik_value.J)

    # -- rules on goals --------------------------------------------------------------------------------
    def is_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """Eq. 8 per goal: every part within its tolerance. Goals (g,) -> (), (B, g) -> (B,)."""
        if self._simple:
            diff = achieved - desired
        else:
            diff = achieved[..., :3] - desired[..., :3]
        success = np.einsum("...i,...i->...", diff, diff) < self.success.position**2
        if self.pose_goal:
            dot = np.abs(np.einsum("...i,...i->...", achieved[..., 3:7], desired[..., 3:7]))
            success &= dot > self._cos_half_tolerance
        return success

    def info(self, achieved: np.ndarray, desired: np.ndarray) -> dict[str, Any]:
        """is_success and distance [m] (and angle [deg], penalty) of one step's goals."""
        diff = achieved - desired if self._simple else achieved[:3] - desired[:3]
        squared = diff.dot(diff)
        success = bool(squared < self.success.position**2)  # as in is_success
        info: dict[str, Any] = {"is_success": success, "distance": math.sqrt(squared)}
        if self.pose_goal:
            dot = abs(float(achieved[3:7].dot(desired[3:7])))
            info["is_success"] = success and dot > self._cos_half_tolerance
            info["angle"] = math.degrees(2 * math.acos(min(dot, 1.0)))
        if self.penalties:
            total, terminates = 0.0, False
            for col, p in self.penalties:
                v = achieved[col]
                if (v < p.above) if p.below else (v > p.above):
                    total += p.reward
                    terminates = terminates or p.terminate
            info["penalty"], info["penalty_terminates"] = total, terminates
        return info

    def target_move(self, achieved: np.ndarray, desired: np.ndarray, goal: np.ndarray) -> FrameMove:
        """The move of the goal frame from `desired` to `goal` (..., g), with the achieved goal's poses known."""
        if self._simple:
            delta = goal - desired
        else:
            delta = goal[..., :3] - desired[..., :3]
        if self.pose_goal:
            old_quat, new_quat = desired[..., 3:7], goal[..., 3:7]
            known = FramePose(achieved[..., :3], achieved[..., 3:7])
        else:
            old_quat = new_quat = self.target_quat
            known = FramePose(achieved[..., :3], None)
        return FrameMove(TARGET_SITE, delta, old_quat, new_quat, self.pose_goal, {self.goal_frame: known})

    def _trial_move(self) -> FrameMove:
        z = np.zeros(self.goal_dim)
        return self.target_move(z, z, z)


def _goal_frame(achieved: Stack, spec: str) -> str:
    """The frame f of a goal map "position(f)" or "position(f), quaternion(f)"; an error otherwise."""
    parts = achieved.parts
    ok = isinstance(parts[0], Position) and (
        len(parts) == 1 or (len(parts) == 2 and isinstance(parts[1], Quaternion) and parts[1].f == parts[0].f)
    )
    if not ok:
        raise InvalidConfig(
            f'goal.map {spec!r} is not a goal map; accepted: "position(f)" or "position(f), quaternion(f)" '
            "for one frame f"
        )
    frame = parts[0].f.name
    if frame == TARGET_SITE:
        raise InvalidConfig(
            f"goal.map {spec!r} reads the goal marker {TARGET_SITE!r} itself; name the TCP or an object"
        )
    return frame


def _penalty_map(penalty: Penalty, model: mujoco.MjModel, joints: tuple[str, ...]) -> TaskMap:
    stack = parse_spec(penalty.map, model, joints)
    if stack.dim != 1 or isinstance(stack.parts[0], Velocity):
        raise InvalidConfig(f"penalty map {penalty.map!r} must be one scalar position-level map (dim 1)")
    m = stack.parts[0]
    if TARGET_SITE in m.frames:
        raise InvalidConfig(f"penalty map {penalty.map!r} reads the goal {TARGET_SITE!r}; penalties must not")
    return m
