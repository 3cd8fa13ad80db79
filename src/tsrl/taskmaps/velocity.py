"""The velocity task map: velocity(map), the exact time derivative y_dot = J q_dot of another map."""

from __future__ import annotations

import numpy as np

from ..exceptions import SpecError
from .base import TaskMap
from .frames import Frame, FrameCache


class Velocity(TaskMap):
    """velocity(m): y_dot = J_m q_dot (dim of m), exact where RAI takes finite differences.

    q_dot is `data.qvel`. The Jacobian returned is J_m itself, which is d y_dot / d q_dot (the
    map is linear in q_dot), not d y_dot / d q: it is what a controller over velocities needs, and
    the latter (the time derivative of J_m for position maps) is not computed.
    """

    def __init__(self, task_map: TaskMap):
        if isinstance(task_map, Velocity):
            raise SpecError(f"velocity of a velocity is not supported: velocity({task_map.spec})")
        self.map = task_map
        self.dim = task_map.dim
        self.spec = f"velocity({task_map.spec})"
        self._y = np.zeros(task_map.dim)

    def frame_refs(self) -> tuple[Frame, ...]:
        return self.map.frame_refs()

    @property
    def frames(self) -> tuple[str, ...]:
        return self.map.frames

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        self.map.evaluate(cache, self._y, J)
        np.dot(J, cache.qvel, out=y)

    def evaluate_from(self, J_map: np.ndarray, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        """`evaluate` given the inner map's Jacobian J_map (dim, nv) at the cached configuration.

        A stack that also holds the inner map passes its rows instead of evaluating the map twice.
        """
        J[:] = J_map
        np.dot(J, cache.qvel, out=y)
