"""Collision task maps: distance (signed, geom to geom) and accumulatedCollisions (total penetration)."""

from __future__ import annotations

import math
from collections import Counter

import mujoco
import numpy as np

from .base import TaskMap
from .frames import FrameCache, resolve_geom


class Distance(TaskMap):
    """distance(a, b): signed distance between geoms a and b (1,): positive apart, negative penetrating.

    (RAI's `distance` has the opposite sign.) From `mj_geomDistance`, which also returns witness
    points on a and b. With n = (p_b - p_a) / d the unit normal from a towards b (dividing by the
    signed distance d flips it when penetrating), J = n^T (Jp_b(s_b) - Jp_a(s_a)) (1, nv), where
    Jp_x(p) is the translational Jacobian of the point p fixed to x's body and s_a, s_b are the
    points of a and b furthest along n and -n (the geoms' support points; by the envelope theorem
    the derivative of d moves exactly these points). Under penetration MuJoCo's witness points are
    only accurate to ~0.2 mm along the surface (its EPA stops at `ccd_tolerance` on the depth, which
    converges faster than the points), so for spheres, capsules, cylinders, ellipsoids and boxes the
    support points are computed in closed form; where a geom's support is a whole edge or face, or
    for other geom types, the witness point is kept. Distances beyond `distmax` read as `distmax`
    with a zero Jacobian; so does a touching pair (|d| < 1e-12), whose normal is undefined.
    """

    dim = 1

    def __init__(self, model: mujoco.MjModel, a: str, b: str, distmax: float = 10.0):
        self.a, self.b = resolve_geom(model, a), resolve_geom(model, b)
        self.body_a, self.body_b = int(model.geom_bodyid[self.a]), int(model.geom_bodyid[self.b])
        body_names = (model.body(self.body_a).name, model.body(self.body_b).name)
        self._names = tuple(dict.fromkeys((a, b, *body_names)))
        self.spec = f"distance({a}, {b})"
        self.distmax = distmax
        self._fromto = np.zeros(6)
        self._n = np.zeros(3)
        self._Ja = np.zeros((3, model.nv))
        self._Jb = np.zeros((3, model.nv))

    @property
    def frames(self) -> tuple[str, ...]:
        """The geoms and the bodies that carry them (a collision map reads geoms, not frames)."""
        return self._names

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        model, data = cache.model, cache.data
        d = mujoco.mj_geomDistance(model, data, self.a, self.b, self.distmax, self._fromto)
        y[0] = d
        if abs(d) < 1e-12 or d >= self.distmax:
            J[:] = 0.0
            return
        p_a, p_b = self._fromto[:3], self._fromto[3:]
        n = self._n
        np.subtract(p_b, p_a, out=n)
        n /= d
        s_a = support_point(model, data, self.a, n, p_a)
        s_b = support_point(model, data, self.b, -n, p_b)
        mujoco.mj_jac(model, data, self._Ja, None, s_a, self.body_a)
        mujoco.mj_jac(model, data, self._Jb, None, s_b, self.body_b)
        self._Jb -= self._Ja
        np.dot(n, self._Jb, out=J[0])


#: |component| of a direction below which a geom's support along it is taken as a whole edge or face.
_FLAT = 1e-6
_SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX = (
    int(t)
    for t in (
        mujoco.mjtGeom.mjGEOM_SPHERE,
        mujoco.mjtGeom.mjGEOM_CAPSULE,
        mujoco.mjtGeom.mjGEOM_ELLIPSOID,
        mujoco.mjtGeom.mjGEOM_CYLINDER,
        mujoco.mjtGeom.mjGEOM_BOX,
    )
)


def support_point(
    model: mujoco.MjModel, data: mujoco.MjData, geom: int, n: np.ndarray, witness: np.ndarray
) -> np.ndarray:
    """The point of `geom` furthest along the unit direction n (3,), world coordinates (3,).

    Closed form for spheres, capsules, ellipsoids, cylinders and boxes. Where the furthest points
    form an edge or a face (a component of n along a geom axis below 1e-6) the coordinate along it
    is taken from `witness` (a point of the geom from the collision query), clamped to the geom;
    other geom types return `witness`. So does a support point that does not lie as far along n as
    the witness (within 1e-5 m): MuJoCo's analytic colliders define some deep penetrations by other
    points (capsule-box: the capsule's sphere nearest to the box), and their witness points are exact.
    """
    s = _support(model, data, geom, n, witness)
    return s if abs(n.dot(s - witness)) < _SAME_DEPTH else witness


#: Largest difference along the normal [m] between a support point and a witness point taken as one depth.
_SAME_DEPTH = 1e-5


def _support(
    model: mujoco.MjModel, data: mujoco.MjData, geom: int, n: np.ndarray, witness: np.ndarray
) -> np.ndarray:
    """`support_point` without the depth check."""
    kind = int(model.geom_type[geom])
    if kind not in (_SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX):
        return witness
    R = data.geom_xmat[geom].reshape(3, 3)
    c = data.geom_xpos[geom]
    size = model.geom_size[geom]
    m = R.T @ n  # n in the geom frame
    w = R.T @ (witness - c)  # the witness point in the geom frame
    if kind == _SPHERE:
        local = size[0] * m
    elif kind == _ELLIPSOID:
        scaled = size * m
        local = size * scaled / np.linalg.norm(scaled)
    elif kind == _BOX:
        local = np.where(np.abs(m) > _FLAT, np.sign(m) * size, np.clip(w, -size, size))
    else:  # capsule or cylinder along the geom's z axis: radius size[0], half-length size[1]
        r, h = size[0], size[1]
        z = np.sign(m[2]) * h if abs(m[2]) > _FLAT else min(max(w[2], -h), h)
        if kind == _CAPSULE:
            local = np.array([r * m[0], r * m[1], z + r * m[2]])
        else:
            radial = math.hypot(m[0], m[1])
            if radial > _FLAT:
                xy = r * m[:2] / radial
            else:  # an end face: keep the witness point's place on it
                xy = w[:2] * min(1.0, r / max(math.hypot(w[0], w[1]), 1e-300))
            local = np.array([xy[0], xy[1], z])
    return c + R @ local


class AccumulatedCollisions(TaskMap):
    """accumulatedCollisions: sum of penetration depths over all contacts, sum_c max(0, -d_c) (1,).

    Runs `mujoco.mj_collision` on `data` itself (collision detection only, no stepping, once per
    evaluation for all maps that read contacts: `FrameCache.collide`), so it is valid right after
    forward kinematics; this overwrites `data.contact` with the contacts of the current configuration.
    For each penetrating contact with normal n (from geom1 to geom2), J += n^T (Jp_1(s_1) - Jp_2(s_2))
    (1, nv), where Jp_i(s) is the translational Jacobian of the point s fixed to geom i's body and
    s_1, s_2 are the geoms' support points along n and -n (`support_point`, as in `Distance`; the
    contact's own points where a support is an edge or face). Where a pair of geoms touches at several
    contacts (a patch) each contact's own point is used. `frames` holds the names of the bodies and
    geoms that can collide.
    """

    dim = 1
    spec = "accumulatedCollisions"

    def __init__(self, model: mujoco.MjModel):
        collides = (model.geom_contype != 0) | (model.geom_conaffinity != 0)
        geoms = np.flatnonzero(collides)
        found = [model.geom(g).name for g in geoms] + [model.body(model.geom_bodyid[g]).name for g in geoms]
        self._names = tuple(dict.fromkeys(n for n in found if n))
        self._J1 = np.zeros((3, model.nv))
        self._J2 = np.zeros((3, model.nv))
        self._row = np.zeros(model.nv)

    @property
    def frames(self) -> tuple[str, ...]:
        """The geoms and the bodies that carry them (a collision map reads geoms, not frames)."""
        return self._names

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        cache.collide()
        model, data = cache.model, cache.data
        y[0] = 0.0
        J[:] = 0.0
        if data.ncon == 0:
            return
        contacts = data.contact
        penetrating = np.flatnonzero(contacts.dist < 0.0)
        pairs = Counter(tuple(g) for g in contacts.geom[penetrating].tolist())
        for i in penetrating:
            c = contacts[i]
            y[0] -= c.dist
            g1, g2 = c.geom
            n = c.frame[:3]
            s1 = s2 = c.pos  # the contact point, midway between the surfaces
            if pairs[(g1, g2)] == 1:  # one contact: the deepest points (several: each its own point)
                s1 = support_point(model, data, g1, n, c.pos - 0.5 * c.dist * n)
                s2 = support_point(model, data, g2, -n, c.pos + 0.5 * c.dist * n)
            mujoco.mj_jac(model, data, self._J1, None, s1, model.geom_bodyid[g1])
            mujoco.mj_jac(model, data, self._J2, None, s2, model.geom_bodyid[g2])
            self._J1 -= self._J2
            np.dot(n, self._J1, out=self._row)
            J[0] += self._row
