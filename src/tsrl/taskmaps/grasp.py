"""Grasp task maps: oppose (RAI's F_GraspOppose), how symmetrically two fingers stand about an object."""

from __future__ import annotations

import mujoco
import numpy as np

from ..exceptions import SpecError
from ..kinematics import names
from .base import TaskMap
from .cores import CORE_KINDS, core_of, core_pair
from .frames import FrameCache

_OBJECTS = (mujoco.mjtObj.mjOBJ_SITE, mujoco.mjtObj.mjOBJ_BODY)
_ACCEPTED = "oppose takes three box, capsule or sphere geoms: two fingers and the object"


class Oppose(TaskMap):
    r"""oppose(a, b, obj): RAI's grasp opposition, y = D_a + D_b (3,), world coordinates [m].

    D_f = p_f - p_obj is RAI's pair vector between finger f and the object with the shapes' radii
    neglected (`F_PairCollision(_vector, neglectRadii=true)`, summed by `F_GraspOppose`): a sphere
    counts as its centre, a capsule as its axis segment, a box as itself (their cores), and p_f,
    p_obj are the cores' closest points, or, where the cores intersect, their deepest points. So
    D_f = s n with s the signed distance of the cores (negative penetrating) and n the unit normal
    from the object towards the finger: continuous through contact. y = 0 when the fingers stand
    symmetrically about the object (apart or pressing into a box's opposite faces equally).

    Jacobian, per finger (docs/taskmaps.md#oppose): with u_1..u_k the unit directions of the two
    features (vertex 0, edge 1 or face 2 directions each) that p_f and p_obj lie on, each turning
    with its body, P the projector onto their span, G = U U^T and D = p_f - p_obj,

    .. math:: J_D = (I - P)(J_p^f(p_f) - J_p^{obj}(p_{obj})) - U^T G^{+} C,\quad
              C_i = (u_i \times D)^T J_r^{body(i)}

    exact wherever the features do not change (almost every configuration; where two faces or a face
    and an edge are parallel the map has no derivative in rotation, and J is that of the points found).
    """

    dim = 3

    def __init__(self, model: mujoco.MjModel, a: str, b: str, obj: str):
        self.spec = f"oppose({a}, {b}, {obj})"
        self.geoms = tuple(self._shape(model, name) for name in (a, b, obj))
        if len(set(self.geoms)) < 3:
            raise SpecError(f"{self.spec}: the same geom twice; {_ACCEPTED}, three different ones")
        self.bodies = tuple(int(model.geom_bodyid[g]) for g in self.geoms)
        found = (a, b, obj, *(model.body(body).name for body in self.bodies))
        self._names = tuple(dict.fromkeys(n for n in found if n))
        self._jp = (np.zeros((3, model.nv)), np.zeros((3, model.nv)))
        self._jr = np.zeros((3, model.nv))
        self._row = np.zeros(model.nv)

    def _shape(self, model: mujoco.MjModel, name: str) -> int:
        """The geom called `name`, with a polytope core; else a one-line SpecError naming the spec."""
        accepted = _ACCEPTED
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gid < 0:
            for kind in _OBJECTS:
                if mujoco.mj_name2id(model, kind, name) >= 0:
                    what = "site" if kind == mujoco.mjtObj.mjOBJ_SITE else "body"
                    raise SpecError(f"{self.spec}: {name!r} is a {what}, not a geom (a shape); {accepted}")
            shapes = [n for n in names(model, "geom") if int(model.geom(n).type[0]) in CORE_KINDS]
            raise SpecError(
                f"{self.spec}: no geom {name!r}; {accepted}; the model's: {', '.join(sorted(shapes))}"
            )
        kind = int(model.geom_type[gid])
        if kind not in CORE_KINDS:
            type_name = mujoco.mjtGeom(kind).name.removeprefix("mjGEOM_").lower()
            raise SpecError(f"{self.spec}: geom {name!r} is a {type_name}; {accepted}")
        return gid

    @property
    def frames(self) -> tuple[str, ...]:
        """The geoms and the bodies that carry them (a collision map reads geoms, not frames)."""
        return self._names

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        model, data = cache.model, cache.data
        y[:] = 0.0
        J[:] = 0.0
        g_obj, body_obj = self.geoms[2], self.bodies[2]
        obj = core_of(model, data, g_obj)
        for g, body in zip(self.geoms[:2], self.bodies[:2]):
            pair = core_pair(core_of(model, data, g), obj)
            D = pair.p_a - pair.p_b
            y += D
            J += self._pair_jacobian(
                model, data, pair.p_a, pair.p_b, D, (body, body_obj), pair.dirs_a, pair.dirs_b
            )

    def _pair_jacobian(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        p_a: np.ndarray,
        p_b: np.ndarray,
        D: np.ndarray,
        bodies: tuple[int, int],
        dirs_a: np.ndarray,
        dirs_b: np.ndarray,
    ) -> np.ndarray:
        """J_D (3, nv) of D = p_a - p_b, p_a fixed to bodies[0], p_b to bodies[1] (see the class)."""
        jp_a, jp_b = self._jp
        mujoco.mj_jac(model, data, jp_a, None, p_a, bodies[0])
        mujoco.mj_jac(model, data, jp_b, None, p_b, bodies[1])
        dJ = jp_a - jp_b
        U = np.concatenate([dirs_a, dirs_b])  # (k, 3)
        if not len(U):
            return dJ
        G_inv = np.linalg.pinv(U @ U.T)
        P = U.T @ G_inv @ U  # projector onto the features' directions
        C = np.zeros((len(U), model.nv))
        owners = [bodies[0]] * len(dirs_a) + [bodies[1]] * len(dirs_b)
        for i, (u, body) in enumerate(zip(U, owners)):
            mujoco.mj_jacBody(model, data, None, self._jr, body)
            np.dot(np.cross(u, D), self._jr, out=C[i])
        return dJ - P @ dJ - U.T @ (G_inv @ C)
