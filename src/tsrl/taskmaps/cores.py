"""Convex cores of geoms and the exact closest (or deepest) pair of points between two of them.

RAI's pair features can neglect the shapes' radii (`F_PairCollision(..., neglectRadii=true)`): a
sphere is then its centre, a capsule its axis segment, a box itself. These cores are polytopes (a
point, a segment, a box), so the vector between their closest points has an exact Jacobian from the
pair of features (vertex, edge, face) the two points lie on, which `core_pair` reports.
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

#: Geom types with a polytope core, and what the core is.
CORE_KINDS: dict[int, str] = {
    int(mujoco.mjtGeom.mjGEOM_SPHERE): "point",
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): "segment",
    int(mujoco.mjtGeom.mjGEOM_BOX): "box",
}
#: Distance [m] within which a point counts as on a feature's boundary (a vertex or an edge end), and
#: below which two cores count as touching.
_TOL = 1e-10
#: |cos| above which two edge directions count as parallel (their cross product is no axis).
_PARALLEL = 1.0 - 1e-12
_SIGNS = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])  # (8, 3)
_BOX_EDGES = [(i, j) for i in range(8) for j in range(8) if i < j and np.sum(_SIGNS[i] != _SIGNS[j]) == 1]


class Core:
    """A geom's core in world coordinates at one configuration: its vertices, edges and faces.

    kind "point" (a sphere's centre), "segment" (a capsule's axis, half-length h along the geom's z
    axis) or "box"; c (3,) centre, R (3, 3) the geom's axes (columns), s (3,) half sizes (box only).
    """

    def __init__(self, kind: str, c: np.ndarray, R: np.ndarray, size: np.ndarray):
        self.kind, self.c, self.R = kind, c, R
        if kind == "point":
            self.vertices = c[None, :]
            self.edges = np.stack([c, c])[None]  # (1, 2, 3): one edge of length 0
        elif kind == "segment":
            h = size[1] * R[:, 2]
            self.vertices = np.stack([c - h, c + h])
            self.edges = self.vertices[None]
        else:
            self.s = size[:3]
            self.vertices = c + (_SIGNS * self.s) @ R.T
            self.edges = np.stack([self.vertices[[i, j]] for i, j in _BOX_EDGES])  # (12, 2, 3)

    def support(self, n: np.ndarray) -> np.ndarray:
        """A point of the core furthest along n (3,)."""
        if self.kind == "point":
            return self.c
        if self.kind == "segment":
            return self.vertices[int(n.dot(self.vertices[1] - self.vertices[0]) > 0.0)]
        return self.c + self.R @ (np.where(self.R.T @ n >= 0.0, 1.0, -1.0) * self.s)

    def interval(self, u: np.ndarray) -> tuple[float, float]:
        """min and max of u . x over the core."""
        m = self.c.dot(u)
        if self.kind == "point":
            return m, m
        if self.kind == "segment":
            r = abs((self.vertices[1] - self.c).dot(u))
        else:
            r = float(np.abs(self.R.T @ u).dot(self.s))
        return m - r, m + r

    def free_directions(self, p: np.ndarray) -> np.ndarray:
        """Unit directions (k, 3) of the smallest feature (vertex 0, edge 1, face 2) that holds p (3,)."""
        if self.kind == "point":
            return np.zeros((0, 3))
        if self.kind == "segment":
            axis = self.R[:, 2]
            h = np.linalg.norm(self.vertices[1] - self.c)
            return axis[None] if abs((p - self.c).dot(axis)) < h - _TOL else np.zeros((0, 3))
        local = self.R.T @ (p - self.c)
        return self.R.T[np.abs(local) < self.s - _TOL]


def core_of(model: mujoco.MjModel, data: mujoco.MjData, geom: int) -> Core:
    """The core of `geom` (a sphere, capsule or box) at the configuration in `data`."""
    kind = CORE_KINDS[int(model.geom_type[geom])]
    return Core(kind, data.geom_xpos[geom], data.geom_xmat[geom].reshape(3, 3), model.geom_size[geom])


class CorePair(NamedTuple):
    """Closest points of two disjoint cores, or the deepest ones of two intersecting cores.

    p_a, p_b (3,): points of core a and core b. w = p_a - p_b is the shortest vector between the
    cores (apart), or, intersecting, minus the shortest translation of a that separates them (a
    moved by -w just touches b): w = s n with s the signed distance (negative penetrating) and n the
    unit normal from b towards a, continuous through contact (RAI's p1 - p2). dirs_a (k_a, 3),
    dirs_b (k_b, 3): unit directions of the features (vertex, edge, face) of a and b that the points
    lie on; apart: whether the cores are disjoint.
    """

    p_a: np.ndarray
    p_b: np.ndarray
    dirs_a: np.ndarray
    dirs_b: np.ndarray
    apart: bool


def core_pair(a: Core, b: Core) -> CorePair:
    """The closest (apart) or deepest (intersecting) pair of points of cores a and b, exactly."""
    if "box" in (a.kind, b.kind):
        depth = _penetration(a, b)
        if depth is not None:
            return depth
    return _closest(a, b)


# -- apart: the closest pair over every pair of features ------------------------------------------------
def _closest(a: Core, b: Core) -> CorePair:
    candidates = [_edges_edges(a.edges, b.edges)]
    if b.kind == "box":
        candidates.append(_points_faces(a.vertices, b))
    if a.kind == "box":
        q, p, d = _points_faces(b.vertices, a)
        candidates.append((p, q, d))
    best = min(candidates, key=lambda c: float(c[2].min()))
    i = int(np.argmin(best[2]))
    p_a, p_b = best[0][i], best[1][i]
    return CorePair(p_a, p_b, a.free_directions(p_a), b.free_directions(p_b), True)


def _edges_edges(ea: np.ndarray, eb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of every segment of ea (n, 2, 3) to every segment of eb (m, 2, 3), which may have
    length 0: points on ea (n*m, 3), on eb (n*m, 3) and their distances (n*m,)."""
    p1 = np.repeat(ea[:, 0], len(eb), axis=0)
    d1 = np.repeat(ea[:, 1] - ea[:, 0], len(eb), axis=0)
    p2 = np.tile(eb[:, 0], (len(ea), 1))
    d2 = np.tile(eb[:, 1] - eb[:, 0], (len(ea), 1))
    r = p1 - p2
    a = np.einsum("ij,ij->i", d1, d1)
    e = np.einsum("ij,ij->i", d2, d2)
    b = np.einsum("ij,ij->i", d1, d2)
    c = np.einsum("ij,ij->i", d1, r)
    f = np.einsum("ij,ij->i", d2, r)
    live_a, live_e = a > 0.0, e > 0.0
    safe_a, safe_e = np.where(live_a, a, 1.0), np.where(live_e, e, 1.0)
    denom = a * e - b * b
    # both of positive length: s on the lines' closest points (0 where parallel), clamped
    s = np.where(
        denom > 1e-12 * a * e, np.clip((b * f - c * e) / np.where(denom > 0.0, denom, 1.0), 0.0, 1.0), 0.0
    )
    t = (b * s + f) / safe_e
    low, high = t < 0.0, t > 1.0  # t clamped to an end, s again for that end
    s = np.where(low, np.clip(-c / safe_a, 0.0, 1.0), np.where(high, np.clip((b - c) / safe_a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    # a segment of length 0 (a point): the other one's closest point to it
    s = np.where(live_e, s, np.clip(-c / safe_a, 0.0, 1.0))
    t = np.where(live_e, t, 0.0)
    s = np.where(live_a, s, 0.0)
    t = np.where(live_a, t, np.where(live_e, np.clip(f / safe_e, 0.0, 1.0), 0.0))
    q1 = p1 + s[:, None] * d1
    q2 = p2 + t[:, None] * d2
    return q1, q2, np.linalg.norm(q1 - q2, axis=1)


def _points_faces(points: np.ndarray, box: Core) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of the box's six faces (closed rectangles) to each point (n, 3):
    the points repeated (6n, 3), the closest face points (6n, 3) and the distances (6n,)."""
    local = (points - box.c) @ box.R  # (n, 3) in the box frame
    out = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            q = np.clip(local, -box.s, box.s)
            q[:, axis] = sign * box.s[axis]
            out.append(q)
    q = np.concatenate(out)  # (6n, 3)
    p = np.tile(points, (6, 1))
    q_world = box.c + q @ box.R.T
    return p, q_world, np.linalg.norm(p - q_world, axis=1)


# -- intersecting: the separating-axis test, whose smallest overlap is the penetration ------------------
def _penetration(a: Core, b: Core) -> CorePair | None:
    """The deepest pair of intersecting cores (at least one a box), or None where they are apart.

    Candidate axes: the boxes' face normals and the cross products of the cores' edge directions; a
    positive gap along any one separates the cores, else the smallest overlap h_a(n) + h_b(-n) over
    the axes and both signs is the penetration depth (the Minkowski difference's nearest facet).
    """
    best: tuple[float, np.ndarray, str, int, int] | None = None  # depth, nu, kind, index a, index b
    axes_a = _edge_directions(a)
    axes_b = _edge_directions(b)
    candidates: list[tuple[np.ndarray, str, int, int]] = []
    if a.kind == "box":
        candidates += [(a.R[:, i], "face_a", i, -1) for i in range(3)]
    if b.kind == "box":
        candidates += [(b.R[:, j], "face_b", -1, j) for j in range(3)]
    for i, ua in enumerate(axes_a):
        for j, ub in enumerate(axes_b):
            if abs(ua.dot(ub)) > _PARALLEL:
                continue
            n = np.cross(ua, ub)
            candidates.append((n / np.linalg.norm(n), "edges", i, j))
    for u, kind, i, j in candidates:
        lo_a, hi_a = a.interval(u)
        lo_b, hi_b = b.interval(u)
        for nu, depth in ((u, hi_a - lo_b), (-u, hi_b - lo_a)):
            if depth < -_TOL:
                return None  # a separating axis: the cores are apart
            if best is None or depth < best[0]:
                best = (depth, nu, kind, i, j)
    assert best is not None  # mypy: a box has face normals
    depth, nu, kind, i, j = best
    w = depth * nu
    if kind == "face_b":  # a's deepest point against b's face
        p_a = a.support(nu)
        return CorePair(p_a, p_a - w, np.zeros((0, 3)), np.delete(b.R.T, j, axis=0), False)
    if kind == "face_a":  # b's deepest point against a's face
        p_b = b.support(-nu)
        return CorePair(p_b + w, p_b, np.delete(a.R.T, i, axis=0), np.zeros((0, 3)), False)
    ua, ub = axes_a[i], axes_b[j]
    p_a, p_b = _lines_closest(a.support(nu), ua, b.support(-nu), ub)
    return CorePair(p_a, p_b, ua[None], ub[None], False)


def _edge_directions(core: Core) -> np.ndarray:
    """Unit directions (k, 3) of the core's edges: a box's axes, a segment's axis, none for a point."""
    if core.kind == "box":
        return core.R.T.copy()
    if core.kind == "segment":
        return core.R[:, 2][None]
    return np.zeros((0, 3))


def _lines_closest(
    p: np.ndarray, u: np.ndarray, q: np.ndarray, v: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Closest points of the lines p + s u and q + t v (unit, not parallel)."""
    r = p - q
    b, c, f = u.dot(v), u.dot(r), v.dot(r)
    denom = 1.0 - b * b
    s = (b * f - c) / denom
    t = (f - b * c) / denom
    return p + s * u, q + t * v
