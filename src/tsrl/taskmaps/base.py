"""The task-map abstraction: phi(q) -> (y, J), evaluated on (model, data) after forward kinematics."""

from __future__ import annotations

import abc
from typing import NamedTuple

import mujoco
import numpy as np


class TaskMapValue(NamedTuple):
    """A task map's value and Jacobian at one configuration."""

    y: np.ndarray  # (dim,)
    J: np.ndarray  # (dim, nv), world-aligned, dy/dq in the tangent space (qvel coordinates)


class TaskMap(abc.ABC):
    """A feature phi: q -> y in R^dim with Jacobian J = dy/dq in R^{dim x nv}.

    Evaluated on (model, data) after forward kinematics (`tsrl.forward_kinematics` or any MuJoCo
    call that runs `mj_kinematics` and `mj_comPos`); never steps the physics.
    """

    #: Number of rows of y and J.
    dim: int

    @abc.abstractmethod
    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> TaskMapValue:
        """Returns (y, J) at the configuration held in `data`."""

    def difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a - b in the map's coordinates; override where coordinates can jump."""
        return a - b
