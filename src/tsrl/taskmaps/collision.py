"""Collision task maps: distance (signed, geom to geom) and accumulatedCollisions (total penetration)."""

from __future__ import annotations

import mujoco
import numpy as np

from .base import TaskMap
from .frames import FrameCache, resolve_geom


class Distance(TaskMap):
    """distance(a, b): signed distance between geoms a and b (1,): positive apart, negative penetrating.

    (RAI's `distance` has the opposite sign.) From `mj_geomDistance`, which also returns the nearest
    points p_a on a and p_b on b. With n = (p_b - p_a) / d the unit normal from a towards b (dividing
    by the signed distance d flips it when penetrating), J = n^T (Jp_b(p_b) - Jp_a(p_a)) (1, nv), where
    Jp_x(p) is the translational Jacobian of the point p fixed to x's body. Distances beyond `distmax`
    read as `distmax` with a zero Jacobian; so does a touching pair (|d| < 1e-12), whose normal is
    undefined.
    """

    dim = 1

    def __init__(self, model: mujoco.MjModel, a: str, b: str, distmax: float = 10.0):
        self.a, self.b = resolve_geom(model, a), resolve_geom(model, b)
        self.body_a, self.body_b = int(model.geom_bodyid[self.a]), int(model.geom_bodyid[self.b])
        body_names = (model.body(self.body_a).name, model.body(self.body_b).name)
        self.frames = tuple(dict.fromkeys((a, b, *body_names)))
        self.spec = f"distance({a}, {b})"
        self.distmax = distmax
        self._fromto = np.zeros(6)
        self._n = np.zeros(3)
        self._Ja = np.zeros((3, model.nv))
        self._Jb = np.zeros((3, model.nv))

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        model, data = cache.model, cache.data
        d = mujoco.mj_geomDistance(model, data, self.a, self.b, self.distmax, self._fromto)
        y[0] = d
        if abs(d) < 1e-12 or d >= self.distmax:
            J[:] = 0.0
            return
        p_a, p_b = self._fromto[:3], self._fromto[3:]
        np.subtract(p_b, p_a, out=self._n)
        self._n /= d
        mujoco.mj_jac(model, data, self._Ja, None, p_a, self.body_a)
        mujoco.mj_jac(model, data, self._Jb, None, p_b, self.body_b)
        self._Jb -= self._Ja
        np.dot(self._n, self._Jb, out=J[0])


class AccumulatedCollisions(TaskMap):
    """accumulatedCollisions: sum of penetration depths over all contacts, sum_c max(0, -d_c) (1,).

    Runs `mujoco.mj_collision` on `data` itself (collision detection only, no stepping), so it is
    valid right after forward kinematics; this overwrites `data.contact` with the contacts of the
    current configuration. For each penetrating contact with normal n (from geom1 to geom2) at
    point p, J += n^T (Jp_1(p) - Jp_2(p)) (1, nv), where Jp_i(p) is the translational Jacobian of
    p fixed to geom i's body. `frames` holds the names of the bodies and geoms that can collide.
    """

    dim = 1
    spec = "accumulatedCollisions"

    def __init__(self, model: mujoco.MjModel):
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        geoms = np.flatnonzero(collides)
        found = [model.geom(g).name for g in geoms] + [model.body(model.geom_bodyid[g]).name for g in geoms]
        self.frames = tuple(dict.fromkeys(n for n in found if n))
        self._J1 = np.zeros((3, model.nv))
        self._J2 = np.zeros((3, model.nv))
        self._row = np.zeros(model.nv)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        model, data = cache.model, cache.data
        mujoco.mj_collision(model, data)
        y[0] = 0.0
        J[:] = 0.0
        if data.ncon == 0:
            return
        contacts = data.contact
        for i in np.flatnonzero(contacts.dist < 0.0):
            c = contacts[i]
            y[0] -= c.dist
            g1, g2 = c.geom
            mujoco.mj_jac(model, data, self._J1, None, c.pos, model.geom_bodyid[g1])
            mujoco.mj_jac(model, data, self._J2, None, c.pos, model.geom_bodyid[g2])
            self._J1 -= self._J2
            np.dot(c.frame[:3], self._J1, out=self._row)
            J[0] += self._row
