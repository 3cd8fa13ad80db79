"""Frames that task maps read (sites or bodies) and a cache of their poses and Jacobians per evaluation."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import mujoco
import numpy as np

from ..exceptions import UnknownName
from ..kinematics import names


@dataclass(frozen=True)
class Frame:
    """A site or body of a model, resolved once when a task map is built.

    `key` identifies the frame within its model: the site id for sites, nsite + body id for bodies.
    """

    name: str
    kind: str  # "site" or "body"
    id: int
    body: int  # the body the frame moves with
    key: int


def resolve_frame(model: mujoco.MjModel, name: str) -> Frame:
    """The site called `name`, else the body called `name` (`world` is the world body).

    Raises:
        UnknownName: neither a site nor a body has that name (the message lists both).
    """
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return Frame(name, "site", sid, int(model.site_bodyid[sid]), sid)
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if bid >= 0:
        return Frame(name, "body", bid, bid, model.nsite + bid)
    raise UnknownName("frame", name, {*names(model, "site"), *names(model, "body")})  # `target` is both


def resolve_geom(model: mujoco.MjModel, name: str) -> int:
    """Id of the geom called `name`; raises UnknownName listing the model's geoms."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    if gid < 0:
        raise UnknownName("geom", name, names(model, "geom"))
    return gid


def body_moves(model: mujoco.MjModel, body: int) -> bool:
    """Whether any joint moves the body: False for the world, mocap bodies and bodies welded to them."""
    while body > 0:
        if model.body_dofnum[body] > 0:
            return True
        body = int(model.body_parentid[body])
    return False


class FrameState:
    """One frame's world pose and Jacobians at the cached configuration; read-only for maps.

    pos (3,) world position; rot (3, 3) R_wf, columns = the frame's axes in world coordinates;
    quat (4,) world orientation (w, x, y, z) composed along the chain as MuJoCo's `xquat` (never
    re-derived from `rot`); jacp, jacr (3, nv) world-aligned translational and rotational Jacobians,
    zero for a frame that no joint moves (`moves` False). pos, rot and (where the site has no
    rotation of its own) quat are views into the bound MjData, so they are never copied.
    """

    __slots__ = ("jacp", "jacq", "jacq_stamp", "jacr", "moves", "pos", "quat", "rot")

    def __init__(self, nv: int, moves: bool):
        self.pos = np.zeros(3)
        self.rot = np.eye(3)
        self.quat = np.array([1.0, 0.0, 0.0, 0.0])
        self.jacp = np.zeros((3, nv))
        self.jacr = np.zeros((3, nv))
        self.jacq = np.zeros((4, nv))
        self.jacq_stamp = -1
        self.moves = moves


class FrameCache:
    """Poses and Jacobians of a fixed set of frames, computed once per `update`.

    The top-level task map owns one cache per model and updates it once per call; all maps
    evaluated in that call read it. `data` and `qvel` hold the configuration of the last update.
    Poses are views into `data`, bound when the cache first sees a given MjData.
    """

    def __init__(self, model: mujoco.MjModel, frames: Iterable[Frame]):
        self.model = model
        self._data: mujoco.MjData | None = None
        self.qvel = np.zeros(model.nv)
        self._stamp = 0
        self._collision_stamp = -1
        self._frames = list({f.key: f for f in frames}.values())
        self._states = {f.key: FrameState(model.nv, body_moves(model, f.body)) for f in self._frames}
        moving = [f for f in self._frames if self._states[f.key].moves]  # the others keep zero Jacobians
        self._site_jacobians = [(self._states[f.key], f.id) for f in moving if f.kind == "site"]
        self._body_jacobians = [(self._states[f.key], f.id) for f in moving if f.kind == "body"]
        self._site_rotations = [
            (self._states[f.key], f.body, model.site_quat[f.id].copy())
            for f in self._frames
            if f.kind == "site" and not np.array_equal(model.site_quat[f.id], [1.0, 0.0, 0.0, 0.0])
        ]

    @property
    def data(self) -> mujoco.MjData:
        """The MjData of the last `update`."""
        if self._data is None:
            raise RuntimeError("FrameCache.update has not been called yet; it binds the cache to an MjData")
        return self._data

    def _bind(self, data: mujoco.MjData) -> None:
        """Points every frame's pose at `data`'s arrays."""
        self._data = data
        self.qvel = data.qvel
        rotated = {id(state) for state, _, _ in self._site_rotations}
        for f in self._frames:
            state = self._states[f.key]
            if f.kind == "site":
                state.pos, state.rot = data.site_xpos[f.id], data.site_xmat[f.id].reshape(3, 3)
            else:
                state.pos, state.rot = data.xpos[f.id], data.xmat[f.id].reshape(3, 3)
            if id(state) not in rotated:
                state.quat = data.xquat[f.body]

    def update(self, data: mujoco.MjData) -> None:
        """Computes what `data` (after forward kinematics) does not hold: site quaternions, Jacobians."""
        if data is not self._data:
            self._bind(data)
        self._stamp += 1
        model = self.model
        if self._site_rotations:
            xquat = data.xquat
            for state, body, local_quat in self._site_rotations:  # site quat = body xquat * site_quat
                mujoco.mju_mulQuat(state.quat, xquat[body], local_quat)
        for state, sid in self._site_jacobians:
            mujoco.mj_jacSite(model, data, state.jacp, state.jacr, sid)
        for state, bid in self._body_jacobians:
            mujoco.mj_jacBody(model, data, state.jacp, state.jacr, bid)

    def collide(self) -> None:
        """Fills `data.contact` with the contacts of the cached configuration (`mujoco.mj_collision`),
        once per update however many maps read contacts."""
        if self._collision_stamp != self._stamp:
            mujoco.mj_collision(self.model, self.data)
            self._collision_stamp = self._stamp

    def __getitem__(self, frame: Frame) -> FrameState:
        return self._states[frame.key]

    def quaternion_jacobian(self, frame: Frame) -> np.ndarray:
        """d quat / dq (4, nv) of the frame, E(quat) jacr, computed at most once per update."""
        state = self._states[frame.key]
        if state.moves and state.jacq_stamp != self._stamp:
            np.dot(quat_rate_matrix(state.quat), state.jacr, out=state.jacq)
            state.jacq_stamp = self._stamp
        return state.jacq


_E_INDEX = np.array([[1, 2, 3], [0, 3, 2], [3, 0, 1], [2, 1, 0]])
_E_SIGN = 0.5 * np.array([[-1.0, -1.0, -1.0], [1.0, 1.0, -1.0], [-1.0, 1.0, 1.0], [1.0, -1.0, 1.0]])


def quat_rate_matrix(q: np.ndarray) -> np.ndarray:
    """E(q) (4, 3) with dq/dt = E(q) w for q = (w, x, y, z) and world angular velocity w.

    From dq/dt = 1/2 (0, w) * q (Hamilton product): E = 1/2 [[-x, -y, -z], [w, z, -y], [-z, w, x],
    [y, -x, w]].
    """
    return np.take(q, _E_INDEX) * _E_SIGN
