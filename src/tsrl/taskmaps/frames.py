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
    raise UnknownName("frame", name, names(model, "site") + names(model, "body"))


def resolve_geom(model: mujoco.MjModel, name: str) -> int:
    """Id of the geom called `name`; raises UnknownName listing the model's geoms."""
    gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
    if gid < 0:
        raise UnknownName("geom", name, names(model, "geom"))
    return gid


class FrameState:
    """One frame's world pose and Jacobians at the cached configuration.

    pos (3,) world position; rot (3, 3) R_wf, columns = the frame's axes in world coordinates;
    quat (4,) world orientation (w, x, y, z) composed along the chain as MuJoCo's `xquat` (never
    re-derived from `rot`); jacp, jacr (3, nv) world-aligned translational and rotational Jacobians.
    """

    __slots__ = ("jacp", "jacr", "pos", "quat", "rot")

    def __init__(self, nv: int):
        self.pos = np.zeros(3)
        self.rot = np.eye(3)
        self.quat = np.array([1.0, 0.0, 0.0, 0.0])
        self.jacp = np.zeros((3, nv))
        self.jacr = np.zeros((3, nv))


class FrameCache:
    """Poses and Jacobians of a fixed set of frames, computed once per `update`.

    The top-level task map owns one cache per model and updates it once per call; all maps
    evaluated in that call read it. `data` and `qvel` hold the configuration of the last update.
    """

    def __init__(self, model: mujoco.MjModel, frames: Iterable[Frame]):
        self.model = model
        self.data: mujoco.MjData | None = None
        self.qvel = np.zeros(model.nv)
        self._states: dict[int, FrameState] = {}
        self._sites: list[tuple[FrameState, int, int, np.ndarray]] = []
        self._bodies: list[tuple[FrameState, int]] = []
        for f in frames:
            if f.key in self._states:
                continue
            state = self._states[f.key] = FrameState(model.nv)
            if f.kind == "site":
                self._sites.append((state, f.id, f.body, model.site_quat[f.id].copy()))
            elif f.id != 0:  # the world body keeps its identity pose and zero Jacobian
                self._bodies.append((state, f.id))

    def update(self, data: mujoco.MjData) -> None:
        """Reads every frame's pose and Jacobian from `data` (after forward kinematics)."""
        model = self.model
        self.data = data
        self.qvel = data.qvel
        xquat = data.xquat
        if self._sites:
            site_xpos, site_xmat = data.site_xpos, data.site_xmat
            for state, sid, bid, local_quat in self._sites:
                state.pos[:] = site_xpos[sid]
                state.rot.flat[:] = site_xmat[sid]
                mujoco.mju_mulQuat(state.quat, xquat[bid], local_quat)
                mujoco.mj_jacSite(model, data, state.jacp, state.jacr, sid)
        if self._bodies:
            xpos, xmat = data.xpos, data.xmat
            for state, bid in self._bodies:
                state.pos[:] = xpos[bid]
                state.rot.flat[:] = xmat[bid]
                state.quat[:] = xquat[bid]
                mujoco.mj_jacBody(model, data, state.jacp, state.jacr, bid)

    def __getitem__(self, frame: Frame) -> FrameState:
        return self._states[frame.key]
