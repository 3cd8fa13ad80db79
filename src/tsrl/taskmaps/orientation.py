"""Orientation task maps: quaternion, quaternionDiff, vectorX/Y/Z, scalarProductXX..ZZ (RAI symbols)."""

from __future__ import annotations

import mujoco
import numpy as np

from .base import TaskMap
from .frames import Frame, FrameCache, resolve_frame
from .position import negative_skew

AXES = "XYZ"


def _aligned_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a - s b with s = sign(a . b) per row (1 at 0), so that q and -q (one orientation) are not far apart.

    a - (-1) b is a + b exactly, so the two branches are the formula itself; `Stack.difference`
    inlines the one-row case.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.ndim == 1 and b.ndim == 1:
        return a + b if a.dot(b) < 0.0 else a - b
    dots = np.einsum("...i,...i->...", a, b)[..., None]
    return np.where(dots < 0.0, a + b, a - b)


class Quaternion(TaskMap):
    """quaternion(f): world orientation of f as a unit quaternion (w, x, y, z) (4,).

    Composed along the kinematic chain as MuJoCo's `xquat` (for a site: body xquat * site quat),
    so it is continuous in q; never re-derived from a rotation matrix. J = E(q) Jr_f (4, nv), with
    dq/dt = E(q) w = 1/2 (0, w) * q for the world angular velocity w (`frames.quat_rate_matrix`).
    """

    dim = 4

    def __init__(self, model: mujoco.MjModel, f: str):
        self.f = resolve_frame(model, f)
        self.spec = f"quaternion({f})"

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f,)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        y[:] = cache[self.f].quat
        J[:] = cache.quaternion_jacobian(self.f)

    def difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return _aligned_difference(a, b)


class QuaternionDiff(TaskMap):
    """quaternionDiff(f, g): q_f - s q_g with s = sign(q_f . q_g) (s = 1 at 0), as RAI defines it (4,).

    J = E(q_f) Jr_f - s E(q_g) Jr_g (4, nv); s is held constant (y jumps where q_f . q_g = 0).
    """

    dim = 4

    def __init__(self, model: mujoco.MjModel, f: str, g: str):
        self.f, self.g = resolve_frame(model, f), resolve_frame(model, g)
        self.spec = f"quaternionDiff({f}, {g})"

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f, self.g)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        q_f, q_g = cache[self.f].quat, cache[self.g].quat
        Jq_f, Jq_g = cache.quaternion_jacobian(self.f), cache.quaternion_jacobian(self.g)
        if np.dot(q_f, q_g) < 0.0:
            np.add(q_f, q_g, out=y)
            np.add(Jq_f, Jq_g, out=J)
        else:
            np.subtract(q_f, q_g, out=y)
            np.subtract(Jq_f, Jq_g, out=J)


class Vector(TaskMap):
    """vectorX/Y/Z(f): axis A of frame f in world coordinates, a = R_f e_A (3,).

    J = -[a]x Jr_f (3, nv), from da/dt = w x a.
    """

    dim = 3

    def __init__(self, model: mujoco.MjModel, axis: str, f: str):
        self.axis = AXES.index(axis)
        self.f = resolve_frame(model, f)
        self.spec = f"vector{axis}({f})"
        self._skew = np.zeros((3, 3))

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f,)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        s = cache[self.f]
        y[:] = s.rot[:, self.axis]
        np.dot(negative_skew(y, self._skew), s.jacr, out=J)


class ScalarProduct(TaskMap):
    """scalarProductAB(f, g): dot product a . b of axis A of f and axis B of g, world coordinates (1,).

    J = (a x b)^T (Jr_f - Jr_g) (1, nv).
    """

    dim = 1

    def __init__(self, model: mujoco.MjModel, axes: str, f: str, g: str):
        self.axes = AXES.index(axes[0]), AXES.index(axes[1])
        self.f, self.g = resolve_frame(model, f), resolve_frame(model, g)
        self.spec = f"scalarProduct{axes}({f}, {g})"
        self._c = np.zeros(3)
        self._dJ = np.zeros((3, model.nv))

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f, self.g)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        sf, sg = cache[self.f], cache[self.g]
        a, b = sf.rot[:, self.axes[0]], sg.rot[:, self.axes[1]]
        y[0] = a @ b
        mujoco.mju_cross(self._c, a, b)
        np.subtract(sf.jacr, sg.jacr, out=self._dJ)
        np.dot(self._c, self._dJ, out=J[0])
