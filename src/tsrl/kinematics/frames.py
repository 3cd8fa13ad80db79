"""Forward kinematics without dynamics, name -> id lookup with helpful errors, site poses."""

from __future__ import annotations

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..assets.ur5e import JOINT_LIMITS, JOINT_NAMES
from ..exceptions import UnknownName

_OBJECT_KINDS = {
    "site": mujoco.mjtObj.mjOBJ_SITE,
    "body": mujoco.mjtObj.mjOBJ_BODY,
    "geom": mujoco.mjtObj.mjOBJ_GEOM,
    "joint": mujoco.mjtObj.mjOBJ_JOINT,
    "actuator": mujoco.mjtObj.mjOBJ_ACTUATOR,
    "key": mujoco.mjtObj.mjOBJ_KEY,
}
_COUNTS = {
    "site": "nsite",
    "body": "nbody",
    "geom": "ngeom",
    "joint": "njnt",
    "actuator": "nu",
    "key": "nkey",
}


def names(model: mujoco.MjModel, kind: str) -> list[str]:
    """All named objects of `kind` (site, body, geom, joint, actuator, key) in the model."""
    obj = _OBJECT_KINDS[kind]
    found = (mujoco.mj_id2name(model, obj, i) for i in range(getattr(model, _COUNTS[kind])))
    return [n for n in found if n]


def name_to_id(model: mujoco.MjModel, kind: str, name: str) -> int:
    """Id of the named object; raises UnknownName listing the model's objects of that kind."""
    idx = mujoco.mj_name2id(model, _OBJECT_KINDS[kind], name)
    if idx < 0:
        raise UnknownName(kind, name, names(model, kind))
    return idx


def as_slice(indices: ArrayLike) -> slice | np.ndarray:
    """The indices as a slice where they are consecutive and ascending (numpy then views instead of
    copying), else as an integer array."""
    idx = [int(i) for i in np.asarray(indices).ravel()]
    consecutive = idx == list(range(idx[0], idx[0] + len(idx)))
    return slice(idx[0], idx[-1] + 1) if consecutive else np.array(idx)


def arm_qpos_indices(model: mujoco.MjModel) -> np.ndarray:
    """qpos addresses of the six UR5e joints, shape (6,), in JOINT_NAMES order."""
    return np.array([model.jnt_qposadr[name_to_id(model, "joint", n)] for n in JOINT_NAMES])


def arm_dof_indices(model: mujoco.MjModel) -> np.ndarray:
    """qvel/dof addresses of the six UR5e joints, shape (6,), in JOINT_NAMES order."""
    return np.array([model.jnt_dofadr[name_to_id(model, "joint", n)] for n in JOINT_NAMES])


def forward_kinematics(model: mujoco.MjModel, data: mujoco.MjData, q: ArrayLike) -> None:
    """Sets the arm's joints to q (6,) and updates frame poses and Jacobian quantities; no dynamics.

    Other generalised coordinates (a free box, say) keep their values in `data`.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (len(JOINT_NAMES),) or not np.all(np.isfinite(q)):
        raise ValueError(f"q must be 6 finite joint angles; got {q!r}")
    data.qpos[arm_qpos_indices(model)] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def site_pose(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """Pose T_ws of site `name` in the world frame, shape (4, 4)."""
    sid = name_to_id(model, "site", name)
    T = np.eye(4)
    T[:3, :3] = data.site_xmat[sid].reshape(3, 3)
    T[:3, 3] = data.site_xpos[sid]
    return T


def random_configurations(rng: np.random.Generator, n: int) -> np.ndarray:
    """n arm configurations uniform within the joint limits, shape (n, 6)."""
    return rng.uniform(JOINT_LIMITS[:, 0], JOINT_LIMITS[:, 1], size=(n, len(JOINT_NAMES)))
