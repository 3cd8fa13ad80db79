"""The suction task map: whether a suction cup (a MuJoCo adhesion actuator) is on and holds something."""

from __future__ import annotations

import mujoco
import numpy as np

from ..exceptions import InvalidConfig, UnknownName
from ..kinematics import names
from .base import TaskMap
from .frames import FrameCache

_BODY_TRANSMISSION = int(mujoco.mjtTrn.mjTRN_BODY)  # adhesion actuators act on a body


class Suction(TaskMap):
    """suction(actuator): the state of an adhesion actuator's suction cup (2,): [on, holding].

    on = 1 where the actuator's control is above 0, else 0; holding = 1 where it is on and a geom of
    the actuator's body touches a geom of another body (a contact of `mujoco.mj_collision`, i.e.
    within the geoms' margin, where adhesion acts), else 0. Reads the contacts of `FrameCache.collide`
    (`mj_collision` on `data` itself, once per evaluation for all maps that read contacts). Both
    values are piecewise constant in q (the control is not a function of q at all): J = 0 (2, nv).
    `frames` names the cup's body and geoms.
    """

    dim = 2

    def __init__(self, model: mujoco.MjModel, actuator: str):
        aid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, actuator)
        if aid < 0:
            raise UnknownName("actuator", actuator, names(model, "actuator"))
        if int(model.actuator_trntype[aid]) != _BODY_TRANSMISSION:
            raise InvalidConfig(f"suction({actuator}): actuator {actuator!r} is not an adhesion actuator")
        self.actuator = aid
        self.body = int(model.actuator_trnid[aid, 0])
        geoms = np.flatnonzero(model.geom_bodyid == self.body)
        self._geoms = frozenset(int(g) for g in geoms)
        self._names = tuple(
            dict.fromkeys(n for n in (model.body(self.body).name, *(model.geom(g).name for g in geoms)) if n)
        )
        self.spec = f"suction({actuator})"

    @property
    def frames(self) -> tuple[str, ...]:
        """The cup's body and its geoms."""
        return self._names

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        data = cache.data
        J[:] = 0.0
        y[0] = 1.0 if data.ctrl[self.actuator] > 0.0 else 0.0
        y[1] = 0.0
        if not y[0]:
            return
        cache.collide()
        for g1, g2 in data.contact.geom[: data.ncon].tolist():
            if (g1 in self._geoms) != (g2 in self._geoms):  # the cup against another body's geom
                y[1] = 1.0
                return
