"""The goal of a task: the achieved and desired goal maps and every rule on them.

A `Goal` owns success (paper eq. 8), the reward (the only reward function: the step's reward and
`compute_reward` both call it), the penalties, the step's goal info, the HER relabelling of an
observation and the move of the goal markers. Goal vectors (g,) or batched (B, g) hold the goal
parts' values, then one column per penalty map (its desired value is 0).

A goal has one or more parts; part i is `position(f_i)` of a frame f_i (the TCP, an object),
optionally followed by `quaternion(f_i)` (a pose part; at most one). Part i's desired value is the
same map of its marker: the mocap body and site `target` for the first part, `target_b`,
`target_c`, ... for the others (a stacking goal: `position(box_a), position(box_b)`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..kinematics import name_to_id
from ..taskmaps import Position, Quaternion, Stack, TaskMap, Velocity, parse_spec
from ..taskmaps.relabel import FrameMove, FramePose, check_relabelable, relabelled
from .reach import check_goal_reachable
from .scenes import TARGET_BODY, TARGET_SITE
from .tasks import Penalty, Task


def _within(squared: Any, dot: Any, tolerance_squared: float, cos_half_tolerance: float) -> Any:
    """Every part within tolerance: the largest squared distance below `tolerance_squared` and, for a
    pose part (dot = |q . q_goal|, else None), the angle within its tolerance."""
    within = squared < tolerance_squared
    return within if dot is None else within & (dot > cos_half_tolerance)


def marker_name(part: int) -> str:
    """The goal marker (mocap body and site) of goal part `part`: target, target_b, target_c, ..."""
    return TARGET_SITE if part == 0 else f"{TARGET_SITE}_{chr(ord('a') + part)}"


def is_marker(frame: str) -> bool:
    """Whether `frame` names a goal marker (target, target_b, ...)."""
    return frame == TARGET_SITE or (
        len(frame) == len(TARGET_SITE) + 2 and frame.startswith(f"{TARGET_SITE}_") and frame[-1].isalpha()
    )


class GoalPart(NamedTuple):
    """One part of a goal: a frame's position, and its orientation for a pose part.

    frame: the achieved frame; marker: the goal marker's name (body and site); position: its 3
    columns in goal vectors; quaternion: its 4 orientation columns (w, x, y, z), or None.
    """

    frame: str
    marker: str
    position: slice
    quaternion: slice | None


class Goal:
    """A task's goal on one model: its maps, their columns and the rules on goal vectors.

    Attributes:
        parts: the goal parts, in column order.
        achieved_maps, desired_maps, penalty_maps: the maps whose values make the achieved goal
            (parts, then penalties) and the desired goal (the markers' maps).
        dim: size g of goal vectors; slices: each part map's and penalty map's columns.
        penalties: (column, Penalty) per penalty map.
    """

    def __init__(self, task: Task, model: mujoco.MjModel, joints: tuple[str, ...]):
        achieved = parse_spec(task.goal.map, model, joints)
        self.parts: tuple[GoalPart, ...] = _parts(achieved, task.goal.map)
        has_pose = any(p.quaternion is not None for p in self.parts)
        if has_pose and task.goal.orientation is None:
            raise InvalidConfig(f"goal.map {task.goal.map!r} has an orientation: give [goal.orientation]")
        if not has_pose and task.goal.orientation is not None:
            raise InvalidConfig('[goal.orientation] needs a pose goal: map = "position(f), quaternion(f)"')
        if len(task.goal.offsets) != len(self.parts) - 1:
            raise InvalidConfig(
                f"goal.offsets has {len(task.goal.offsets)} entries for a goal of {len(self.parts)} parts "
                f"({task.goal.map!r}); give one [x, y, z] offset [m] from the first part per later part"
            )
        self.pose = has_pose
        _check_parts_apart(model, self.parts, task.goal.offsets)
        check_goal_reachable(task, model, joints, self.parts[0].frame)
        self.achieved_maps: list[TaskMap] = list(achieved.parts)
        desired = [
            f"position({p.marker})" + (f", quaternion({p.marker})" if p.quaternion is not None else "")
            for p in self.parts
        ]
        self.desired_maps: list[TaskMap] = list(parse_spec(", ".join(desired), model).parts)
        self.penalty_maps: list[TaskMap] = [_penalty_map(p, model, joints) for p in task.success.penalties]
        self.slices: dict[str, slice] = {}
        col = 0
        for m in (*self.achieved_maps, *self.penalty_maps):
            self.slices[m.spec] = slice(col, col + m.dim)
            col += m.dim
        self.dim = col
        self.penalties: tuple[tuple[int, Penalty], ...] = tuple(
            (self.slices[m.spec].start, p) for m, p in zip(self.penalty_maps, task.success.penalties)
        )
        self._tolerance_squared = task.success.position**2
        self._cos_half_tolerance = math.cos(math.radians(task.success.orientation) / 2)
        self._reward_scale = task.success.reward_scale
        scale = self._reward_scale
        self._reward_tolerance_squared = (task.success.position * scale) ** 2
        self._cos_half_reward_tolerance = math.cos(math.radians(task.success.orientation * scale) / 2)
        self._success_value, self._failure_value = (1.0, 0.0) if task.success.reward == "0/1" else (0.0, -1.0)
        # One goal part read whole (the reach tasks): success compares the whole vectors.
        self._one_position = len(self.parts) == 1 and not self.pose and not self.penalties
        bodies = [name_to_id(model, "body", _marker_body(p.marker)) for p in self.parts]
        self._mocap = [int(model.body_mocapid[b]) for b in bodies]
        for part, mocap in zip(self.parts, self._mocap):
            if mocap < 0:
                raise InvalidConfig(
                    f'the scene\'s body {_marker_body(part.marker)!r} must be a mocap body (mocap="true")'
                )
        #: Each marker's orientation in the scene (a position part's marker keeps it).
        self.marker_quats = [model.body_quat[b].copy() for b in bodies]

    # -- rules on goal vectors -----------------------------------------------------------------------
    def success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """Eq. 8: every part within its tolerance. Goals (g,) -> (), (B, g) -> (B,); bool."""
        return self._evaluate(achieved, desired)[0]

    def reward(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """The reward: the success value where every part is within `reward_scale` of its tolerances
        (SuccessSpec; at 1, where `success`), else the failure value (0/1, or -1/0 with reward =
        "-1/0"), plus each penalty that applies to the achieved goal.

        Goals (g,) -> (), (B, g) -> (B,); float64.
        """
        success, squared, dot, penalty, _ = self._evaluate(achieved, desired)
        return self._reward(self._rewarded(success, squared, dot), penalty)

    def task_reward(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        """`reward` with the reward's success at the tolerances themselves (reward_scale 1): the
        reward a demonstration file stores, whatever the run's scale. Shapes as `reward`."""
        success, _, _, penalty, _ = self._evaluate(achieved, desired)
        return self._reward(success, penalty)

    def outcome(self, achieved: np.ndarray, desired: np.ndarray) -> tuple[float, dict[str, Any]]:
        """One step's reward (as `reward`) and goal info of goals (g,): is_success (at the
        tolerances), distance [m] (the largest part's), angle [deg] (pose goals), penalty and
        penalty_terminates (with penalties)."""
        success, squared, dot, penalty, terminates = self._evaluate(achieved, desired)
        info: dict[str, Any] = {"is_success": bool(success), "distance": math.sqrt(squared)}
        if dot is not None:
            info["angle"] = math.degrees(2 * math.acos(min(float(dot), 1.0)))
        if self.penalties:
            info["penalty"], info["penalty_terminates"] = float(penalty), bool(terminates)
        return float(self._reward(self._rewarded(success, squared, dot), penalty)), info

    def _rewarded(self, success: Any, squared: Any, dot: Any) -> Any:
        """Where the reward counts success: `success` itself at reward_scale 1, else every part within
        reward_scale of its tolerances."""
        if self._reward_scale == 1.0:
            return success
        return _within(squared, dot, self._reward_tolerance_squared, self._cos_half_reward_tolerance)

    def _reward(self, success: np.ndarray, penalty: np.ndarray | float) -> np.ndarray:
        # failure + success * (success - failure value): exact for both conventions (gap 1).
        return self._failure_value + success * (self._success_value - self._failure_value) + penalty

    def _evaluate(self, achieved: np.ndarray, desired: np.ndarray) -> tuple[Any, Any, Any, Any, Any]:
        """(success, the largest part's squared distance, |q . q_goal| of the pose part or None,
        summed penalty, whether a terminating penalty applies), each of shape (...)."""
        if self._one_position:
            diff = achieved - desired
            squared = np.vecdot(diff, diff)
            return squared < self._tolerance_squared, squared, None, 0.0, False
        squared = None
        dot = None
        for part in self.parts:
            diff = achieved[..., part.position] - desired[..., part.position]
            d2 = np.vecdot(diff, diff)
            squared = d2 if squared is None else np.maximum(squared, d2)
            if part.quaternion is not None:
                dot = np.abs(np.vecdot(achieved[..., part.quaternion], desired[..., part.quaternion]))
        success = _within(squared, dot, self._tolerance_squared, self._cos_half_tolerance)
        penalty: Any = 0.0
        terminates: Any = False
        for col, p in self.penalties:
            value = achieved[..., col]
            applies = value < p.above if p.below else value > p.above
            penalty = penalty + np.where(applies, p.reward, 0.0)
            if p.terminate:
                terminates = terminates | applies
        return success, squared, dot, penalty, terminates

    # -- relabelling ------------------------------------------------------------------------------------
    def relabel(self, obs_map: Stack, obs: dict[str, np.ndarray], new_goal: Any) -> dict[str, np.ndarray]:
        """The observation dict the environment would have emitted with the markers moved to `new_goal`.

        The goal-dependent features of `obs_map` are recomputed; penalty columns of the new desired
        goal are 0. Arrays (d,) or batched (B, d); `new_goal` (g,) or (B, g).
        """
        achieved = np.asarray(obs["achieved_goal"], dtype=np.float64)
        desired = np.asarray(obs["desired_goal"], dtype=np.float64)
        goal = np.broadcast_to(np.asarray(new_goal, dtype=np.float64), desired.shape)
        observation = np.asarray(obs["observation"], np.float64)
        for move in self.marker_moves(achieved, desired, goal):
            observation = relabelled(obs_map, observation, move)
        desired_goal = goal.copy()
        for col, _ in self.penalties:
            desired_goal[..., col] = 0.0
        return {
            "observation": observation,
            "achieved_goal": np.array(achieved),
            "desired_goal": desired_goal,
        }

    def marker_moves(self, achieved: np.ndarray, desired: np.ndarray, goal: np.ndarray) -> list[FrameMove]:
        """Each marker's move from `desired` to `goal` (..., g), with the achieved frames' poses known."""
        known = {
            p.frame: FramePose(
                achieved[..., p.position], achieved[..., p.quaternion] if p.quaternion is not None else None
            )
            for p in self.parts
        }
        moves = []
        for part, scene_quat in zip(self.parts, self.marker_quats):
            cols = slice(None) if self._one_position else part.position
            delta = goal[..., cols] - desired[..., cols]
            if part.quaternion is not None:
                old_quat, new_quat = desired[..., part.quaternion], goal[..., part.quaternion]
            else:
                old_quat = new_quat = scene_quat
            moves.append(
                FrameMove(part.marker, delta, old_quat, new_quat, part.quaternion is not None, known)
            )
        return moves

    def check_relabelable(self, obs_map: Stack) -> None:
        """Raises NotRelabelable unless every feature of `obs_map` can be relabelled for every marker."""
        z = np.zeros(self.dim)
        for move in self.marker_moves(z, z, z):
            check_relabelable(obs_map, move)

    # -- markers ----------------------------------------------------------------------------------------
    def place_marker(
        self, data: mujoco.MjData, part: int, pos: np.ndarray, quat: np.ndarray | None = None
    ) -> None:
        """Puts part `part`'s marker at `pos` (3,) and, for a pose part, orientation `quat` (4,)."""
        mocap = self._mocap[part]
        data.mocap_pos[mocap] = pos
        if quat is not None:
            data.mocap_quat[mocap] = quat

    def marker_mocap(self, part: int) -> int:
        """The mocap index of part `part`'s marker (data.mocap_pos row)."""
        return self._mocap[part]

    def place(self, data: mujoco.MjData, goal: np.ndarray) -> None:
        """Puts every marker at its part of the goal vector `goal` (g,) (no kinematics)."""
        for i, part in enumerate(self.parts):
            quat = goal[part.quaternion] if part.quaternion is not None else None
            self.place_marker(data, i, goal[part.position], quat)


def _marker_body(marker: str) -> str:
    """The marker's mocap body (the first marker's body is TARGET_BODY; the others share the site's name)."""
    return TARGET_BODY if marker == TARGET_SITE else marker


def _parts(achieved: Stack, spec: str) -> tuple[GoalPart, ...]:
    """The goal parts of an achieved-goal map; an error naming what is accepted otherwise."""
    accepted = (
        'accepted: "position(f)", a pose "position(f), quaternion(f)", or several frames '
        '"position(a), position(b), ..." (at most one of them followed by its quaternion)'
    )
    parts: list[GoalPart] = []
    col = 0
    for m in achieved.parts:
        if isinstance(m, Position):
            frame = m.f.name
            if is_marker(frame):
                raise InvalidConfig(
                    f"goal.map {spec!r} reads the goal marker {frame!r} itself; name the TCP or an object"
                )
            if any(p.frame == frame for p in parts):
                raise InvalidConfig(f"goal.map {spec!r} names frame {frame!r} twice; {accepted}")
            parts.append(GoalPart(frame, marker_name(len(parts)), slice(col, col + 3), None))
            col += 3
        elif (
            isinstance(m, Quaternion)
            and parts
            and m.f.name == parts[-1].frame
            and parts[-1].quaternion is None
            and all(p.quaternion is None for p in parts)
        ):
            parts[-1] = parts[-1]._replace(quaternion=slice(col, col + 4))
            col += 4
        else:
            raise InvalidConfig(f"goal.map {spec!r} is not a goal map; {accepted}")
    return tuple(parts)


def _check_parts_apart(
    model: mujoco.MjModel, parts: tuple[GoalPart, ...], offsets: tuple[tuple[float, float, float], ...]
) -> None:
    """Refuses goal offsets that put one part's object inside another's (their boxes of half-extents
    overlapping on every axis at their goals)."""
    goals = [np.zeros(3), *(np.asarray(o, dtype=np.float64) for o in offsets)]
    extents = [_half_extents(model, p.frame) for p in parts]
    for i in range(len(parts)):
        for j in range(i + 1, len(parts)):
            a, b = extents[i], extents[j]
            if a is None or b is None:
                continue
            if np.all(np.abs(goals[j] - goals[i]) < a + b - 1e-9):
                raise InvalidConfig(
                    f"goal.offsets put {parts[j].frame!r} inside {parts[i].frame!r} at their goals (offset "
                    f"{(goals[j] - goals[i]).round(4).tolist()} m, half-extents {a.round(4).tolist()} and "
                    f"{b.round(4).tolist()} m); accepted: offsets that keep the objects apart"
                )


def _half_extents(model: mujoco.MjModel, frame: str) -> np.ndarray | None:
    """Half-extents (3,) [m] of the box and sphere geoms of the body called `frame` (in its frame), or
    None where it is no body or has none."""
    body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, frame)
    if body < 0:
        return None
    extent = None
    for g in range(model.body_geomadr[body], model.body_geomadr[body] + model.body_geomnum[body]):
        kind = int(model.geom_type[g])
        if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
            h = model.geom_size[g].copy()
        elif kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
            h = np.full(3, model.geom_size[g, 0])
        else:
            continue
        h = np.abs(model.geom_pos[g]) + h
        extent = h if extent is None else np.maximum(extent, h)
    return extent


def _penalty_map(penalty: Penalty, model: mujoco.MjModel, joints: tuple[str, ...]) -> TaskMap:
    stack = parse_spec(penalty.map, model, joints)
    if stack.dim != 1 or isinstance(stack.parts[0], Velocity):
        raise InvalidConfig(f"penalty map {penalty.map!r} must be one scalar position-level map (dim 1)")
    m = stack.parts[0]
    if any(is_marker(frame) for frame in m.frames):
        raise InvalidConfig(f"penalty map {penalty.map!r} reads the goal {TARGET_SITE!r}; penalties must not")
    return m


def goal_positions(first: np.ndarray, offsets: Sequence[Sequence[float]]) -> list[np.ndarray]:
    """Every part's desired position: the first part's (3,), then first + offset for each later part."""
    return [first, *(first + np.asarray(o, dtype=np.float64) for o in offsets)]
