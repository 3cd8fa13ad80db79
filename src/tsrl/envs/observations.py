"""Observation presets and the step plan: every task map a step needs, in one stack evaluated once,
with named rows.

Rows of the stack: the observation's maps first (so `observation` is its leading rows), then the
maps of the IK, the achieved and desired goal and the penalties that the observation lacks (a map
already there is read there). Goals and the IK read their rows as views where the rows follow one
another, and gather them into buffers where they do not.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..kinematics import as_slice
from ..taskmaps import Stack, TaskMap, TaskMapValue, parse_spec
from .goals import Goal

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

#: The name of the observation rows that hold the policy's previous actions (`Task.previous_actions`),
#: after the task maps' rows.
PREVIOUS_ACTIONS = "previous_actions"


def push_previous_action(history: np.ndarray, action: np.ndarray) -> None:
    """Puts `action` (k,) first in `history` (n, k), in place: the rows of PREVIOUS_ACTIONS are the
    last n actions, newest first (the environment's step and the deployment controller's)."""
    if history.size:
        history[1:] = history[:-1]
        history[0] = action


def parse_observation(spec: str, model: mujoco.MjModel, joints: tuple[str, ...] | None = None) -> Stack:
    """The observation's Stack of a spec that may name OBS_PRESETS (tsrl.taskmaps.parse_spec)."""
    return parse_spec(spec, model, joints, OBS_PRESETS)


class _Rows:
    """Rows of the step stack read as one vector: a view where they are consecutive, else gathered."""

    def __init__(self, rows: list[int], width: int):
        self.index = as_slice(rows)
        self.n = len(rows)
        self.width = width  # >= n: extra columns stay 0 (the desired value of penalty maps)
        self._view = isinstance(self.index, slice) and width == self.n

    def bind(self, y: np.ndarray) -> np.ndarray:
        """The rows of values y: a view, or a buffer (width,) that `gather` fills."""
        return y[self.index] if self._view else np.zeros(self.width)

    def bind_jacobian(self, J: np.ndarray) -> np.ndarray:
        """The rows of Jacobian J: a view, or a buffer (n, nv) that `gather_jacobian` fills."""
        return J[self.index] if self._view else np.empty((self.n, J.shape[1]))

    def gather(self, y: np.ndarray, out: np.ndarray) -> None:
        """Copies the rows of y into the buffer `bind` made (nothing to do for a view)."""
        if isinstance(self.index, slice):
            if not self._view:
                out[: self.n] = y[self.index]
        else:
            np.take(y, self.index, out=out[: self.n])

    def gather_jacobian(self, J: np.ndarray, out: np.ndarray) -> None:
        """Copies the rows of J into the buffer `bind_jacobian` made (nothing to do for a view)."""
        if isinstance(self.index, slice):
            if not self._view:
                out[:] = J[self.index]
        else:
            np.take(J, self.index, axis=0, out=out)


class StepPlan:
    """The maps of one step (observation, IK, goals, penalties) in one stack, evaluated once.

    Attributes:
        obs_map: the observation's Stack; views: (observation, achieved goal, desired goal) of the
        last evaluation, live buffers (copy before handing them out); ik_value: the IK map's value
        and Jacobian of the last evaluation.
    """

    def __init__(
        self, model: mujoco.MjModel, obs_spec: str, goal: Goal, ik_map: Stack | None, joints: tuple[str, ...]
    ):
        self.obs_map = parse_observation(obs_spec, model, joints)
        step_parts = list(self.obs_map.parts)
        for part in (
            *(ik_map.parts if ik_map else ()),
            *goal.achieved_maps,
            *goal.desired_maps,
            *goal.penalty_maps,
        ):
            if all(part.spec != p.spec for p in step_parts):
                step_parts.append(part)
        self._maps = Stack(step_parts)
        rows = self._maps.slices  # a spec's first occurrence is keyed by the spec itself

        def rows_of(maps: list[TaskMap]) -> list[int]:
            return [i for m in maps for i in range(rows[m.spec].start, rows[m.spec].stop)]

        self._achieved = _Rows(rows_of([*goal.achieved_maps, *goal.penalty_maps]), goal.dim)
        self._desired = _Rows(rows_of(goal.desired_maps), goal.dim)
        self._ik = _Rows(rows_of(list(ik_map.parts)), ik_map.dim) if ik_map else None
        self._value: TaskMapValue | None = None
        self.views: tuple[np.ndarray, np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0), np.zeros(0))
        self.ik_value: TaskMapValue | None = None

    def evaluate(self, model: mujoco.MjModel, data: mujoco.MjData, kinematics: bool = True) -> None:
        """Evaluates every map of the step once at the current state (after the physics substeps)."""
        if kinematics:
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
        value = self._maps.in_place(model, data)
        y, J = value
        if value is not self._value:  # the stack's buffers, the same from the first call on: view them once
            self._value = value
            self.views = (y[: self.obs_map.dim], self._achieved.bind(y), self._desired.bind(y))
            if self._ik is not None:
                self.ik_value = TaskMapValue(self._ik.bind(y), self._ik.bind_jacobian(J))
        self._achieved.gather(y, self.views[1])
        self._desired.gather(y, self.views[2])
        if self._ik is not None and self.ik_value is not None:
            self._ik.gather(y, self.ik_value.y)
            self._ik.gather_jacobian(J, self.ik_value.J)
