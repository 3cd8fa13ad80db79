"""The gripper task map: gripperWidth, the opening width that a gripper's servo drives."""

from __future__ import annotations

import mujoco
import numpy as np

from ..exceptions import SpecError, UnknownName
from ..kinematics import names
from .base import TaskMap
from .frames import FrameCache

_JOINT, _TENDON = int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_TENDON)
_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))
_WRAP_JOINT = int(mujoco.mjtWrap.mjWRAP_JOINT)


class GripperWidth(TaskMap):
    """gripperWidth(actuator): the length of a gripper servo's transmission (1,), in its control's units.

    For a parallel gripper whose servo drives a fixed tendon over its finger slide joints (the
    `panda_gripper` robot's `gripper`: length q_left + q_right), or one finger slide joint, that is
    the opening width [m], which the servo's control sets. y = g sum_i c_i q_i (MuJoCo's
    `actuator_length`): g the actuator's gear, c_i the tendon's joint coefficients (one joint, c = 1,
    for a joint transmission); J = g sum_i c_i e_{dof_i}^T (1, nv), constant. Reads no frame: moving
    any frame leaves it unchanged.
    """

    dim = 1

    def __init__(self, model: mujoco.MjModel, actuator: str):
        self.spec = f"gripperWidth({actuator})"
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
        if aid < 0:
            raise UnknownName("actuator", actuator, names(model, "actuator"))
        accepted = "gripperWidth takes an actuator on a slide or hinge joint or on a fixed tendon"
        gear = float(model.actuator_gear[aid, 0])
        trn, target = int(model.actuator_trntype[aid]), int(model.actuator_trnid[aid, 0])
        if trn == _JOINT and int(model.jnt_type[target]) in _ONE_DOF:
            terms = [(target, 1.0)]
        elif trn == _TENDON:
            adr, num = int(model.tendon_adr[target]), int(model.tendon_num[target])
            wraps = range(adr, adr + num)
            if any(int(model.wrap_type[k]) != _WRAP_JOINT for k in wraps):
                raise SpecError(f"{self.spec}: actuator {actuator!r} drives a spatial tendon; {accepted}")
            terms = [(int(model.wrap_objid[k]), float(model.wrap_prm[k])) for k in wraps]
        else:
            raise SpecError(
                f"{self.spec}: actuator {actuator!r} has no joint or fixed-tendon transmission; {accepted}"
            )
        self._qadr = np.array([model.jnt_qposadr[j] for j, _ in terms])
        self._coef = gear * np.array([c for _, c in terms])
        self._J = np.zeros((1, model.nv))
        for (j, _), c in zip(terms, self._coef):
            self._J[0, model.jnt_dofadr[j]] += c

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        y[0] = self._coef.dot(cache.data.qpos[self._qadr])
        J[:] = self._J
