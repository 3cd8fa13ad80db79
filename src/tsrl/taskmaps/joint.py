"""Joint task maps: jointState and jointLimits over the six UR5e arm joints."""

from __future__ import annotations

import mujoco
import numpy as np

from ..assets.ur5e import JOINT_NAMES
from ..kinematics import arm_dof_indices, arm_qpos_indices, name_to_id
from .base import TaskMap
from .frames import FrameCache


class JointState(TaskMap):
    """jointState: angles q (6,) of the six UR5e arm joints in `JOINT_NAMES` order.

    Other joints (the free joint of a box, say) are not part of it. J (6, nv) selects the arm's
    dofs: J[i, dof_i] = 1, zeros elsewhere.
    """

    dim = len(JOINT_NAMES)
    spec = "jointState"

    def __init__(self, model: mujoco.MjModel):
        self._qadr = arm_qpos_indices(model)
        self._J = np.zeros((self.dim, model.nv))
        self._J[np.arange(self.dim), arm_dof_indices(model)] = 1.0

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        y[:] = cache.data.qpos[self._qadr]
        J[:] = self._J


class JointLimits(TaskMap):
    """jointLimits: signed margins [lo - q, q - hi] (12,) of the six arm joints; all <= 0 inside.

    lo, hi are the model's joint ranges (`jnt_range`). J = [-S; S] (12, nv), S the jointState selector.
    """

    dim = 2 * len(JOINT_NAMES)
    spec = "jointLimits"

    def __init__(self, model: mujoco.MjModel):
        joints = [name_to_id(model, "joint", n) for n in JOINT_NAMES]
        self._qadr = arm_qpos_indices(model)
        self._lo = model.jnt_range[joints, 0].copy()
        self._hi = model.jnt_range[joints, 1].copy()
        n = len(JOINT_NAMES)
        self._J = np.zeros((self.dim, model.nv))
        self._J[np.arange(n), arm_dof_indices(model)] = -1.0
        self._J[n + np.arange(n), arm_dof_indices(model)] = 1.0

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        q = cache.data.qpos[self._qadr]
        n = len(self._lo)
        np.subtract(self._lo, q, out=y[:n])
        np.subtract(q, self._hi, out=y[n:])
        J[:] = self._J
