"""Position task maps: position, positionDiff, positionRel (RAI feature symbols)."""

from __future__ import annotations

import mujoco
import numpy as np

from .base import TaskMap
from .frames import Frame, FrameCache, resolve_frame

#: [v]x = v[_SKEW_INDEX] * _SKEW_SIGN for v = (x, y, z): [[0, -z, y], [z, 0, -x], [-y, x, 0]].
_SKEW_INDEX = np.array([[0, 2, 1], [2, 0, 0], [1, 0, 0]])
_SKEW_SIGN = np.array([[0.0, -1.0, 1.0], [1.0, 0.0, -1.0], [-1.0, 1.0, 0.0]])
_NEGATIVE_SKEW_SIGN = -_SKEW_SIGN


def skew(v: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Writes the cross-product matrix [v]x (3, 3) of v (3,) into `out` (so [v]x w = v x w)."""
    return np.multiply(v[_SKEW_INDEX], _SKEW_SIGN, out=out)


def negative_skew(v: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Writes -[v]x = [v]x^T (3, 3) into `out` (so -[v]x w = w x v)."""
    return np.multiply(v[_SKEW_INDEX], _NEGATIVE_SKEW_SIGN, out=out)


class Position(TaskMap):
    """position(f): world position p_f (3,) of frame f; J = Jp_f (3, nv)."""

    dim = 3

    def __init__(self, model: mujoco.MjModel, f: str):
        self.f = resolve_frame(model, f)
        self.spec = f"position({f})"

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f,)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        s = cache[self.f]
        y[:] = s.pos
        J[:] = s.jacp


class PositionDiff(TaskMap):
    """positionDiff(f, g): p_f - p_g (3,) in world coordinates; J = Jp_f - Jp_g (3, nv)."""

    dim = 3

    def __init__(self, model: mujoco.MjModel, f: str, g: str):
        self.f, self.g = resolve_frame(model, f), resolve_frame(model, g)
        self.spec = f"positionDiff({f}, {g})"

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f, self.g)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        sf, sg = cache[self.f], cache[self.g]
        np.subtract(sf.pos, sg.pos, out=y)
        np.subtract(sf.jacp, sg.jacp, out=J)


class PositionRel(TaskMap):
    """positionRel(f, g): p_f expressed in frame g, R_g^T (p_f - p_g) (3,).

    J = R_g^T (Jp_f - Jp_g + [p_f - p_g]x Jr_g) (3, nv): the last term is the rotation of g.
    """

    dim = 3

    def __init__(self, model: mujoco.MjModel, f: str, g: str):
        self.f, self.g = resolve_frame(model, f), resolve_frame(model, g)
        self.spec = f"positionRel({f}, {g})"
        self._v = np.zeros(3)
        self._skew = np.zeros((3, 3))
        self._Jw = np.zeros((3, model.nv))

    def frame_refs(self) -> tuple[Frame, ...]:
        return (self.f, self.g)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        sf, sg = cache[self.f], cache[self.g]
        v, Jw = self._v, self._Jw
        np.subtract(sf.pos, sg.pos, out=v)
        np.dot(v, sg.rot, out=y)  # R_g^T v
        np.dot(skew(v, self._skew), sg.jacr, out=Jw)
        Jw += sf.jacp
        Jw -= sg.jacp
        np.dot(sg.rot.T, Jw, out=J)
