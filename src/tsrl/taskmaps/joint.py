"""Joint task maps: jointState and jointLimits over the controlled joints given to them."""

from __future__ import annotations

import mujoco
import numpy as np

from ..exceptions import SpecError
from ..kinematics import Joints, arm_dof_indices, arm_qpos_indices, controlled_joints, joint_limits
from .base import TaskMap
from .frames import FrameCache


class JointState(TaskMap):
    """jointState: positions q (n,) of the controlled joints, in the order given.

    `joints` names hinge or slide joints; by default every hinge and slide joint of the model (the
    six arm joints in the UR5e scenes; a box's free joint is never part of it). J (n, nv) selects the
    joints' dofs: J[i, dof_i] = 1, zeros elsewhere.
    """

    spec = "jointState"

    def __init__(self, model: mujoco.MjModel, joints: Joints = None):
        self.joints = controlled_joints(model, joints)
        self.dim = len(self.joints)
        self._qadr = arm_qpos_indices(model, self.joints)
        self._J = np.zeros((self.dim, model.nv))
        self._J[np.arange(self.dim), arm_dof_indices(model, self.joints)] = 1.0

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        y[:] = cache.data.qpos[self._qadr]
        J[:] = self._J


class JointLimits(TaskMap):
    """jointLimits: signed margins [lo - q, q - hi] (2n,) of the controlled joints; all <= 0 inside.

    Joints as in `JointState`; lo, hi are the model's joint ranges (`jnt_range`), so every joint must
    have limits. J = [-S; S] (2n, nv), S the jointState selector.
    """

    spec = "jointLimits"

    def __init__(self, model: mujoco.MjModel, joints: Joints = None):
        self.joints = controlled_joints(model, joints)
        n = len(self.joints)
        self.dim = 2 * n
        limits = joint_limits(model, self.joints)
        unlimited = [j for j, lim in zip(self.joints, limits) if not np.isfinite(lim).all()]
        if unlimited:
            raise SpecError(f"jointLimits needs joints with limits; {', '.join(unlimited)} have none")
        self._qadr = arm_qpos_indices(model, self.joints)
        self._lo = limits[:, 0].copy()
        self._hi = limits[:, 1].copy()
        dofs = arm_dof_indices(model, self.joints)
        self._J = np.zeros((self.dim, model.nv))
        self._J[np.arange(n), dofs] = -1.0
        self._J[n + np.arange(n), dofs] = 1.0

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        q = cache.data.qpos[self._qadr]
        n = len(self._lo)
        np.subtract(self._lo, q, out=y[:n])
        np.subtract(q, self._hi, out=y[n:])
        J[:] = self._J
