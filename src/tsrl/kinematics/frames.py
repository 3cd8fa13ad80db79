"""Forward kinematics without dynamics, the controlled joints of any model, name -> id lookup with
helpful errors, site poses.

Nothing here knows a robot: the controlled joints are an argument (as in mink's `Configuration`),
by default every hinge and slide joint of the model (`controlled_joints`).
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..exceptions import InvalidConfig, UnknownName

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
_HINGE, _SLIDE = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
_JOINT_TYPES = {int(v): k[6:].lower() for k, v in mujoco.mjtJoint.__members__.items()}  # 0: "free"

#: Which joints to control: names in order, or None for every hinge and slide joint of the model.
Joints = Sequence[str] | None


def names(model: mujoco.MjModel, kind: str) -> list[str]:
    """All named objects of `kind` (site, body, geom, joint, actuator, key) in the model."""
    obj = _OBJECT_KINDS[kind]
    found = (mujoco.mj_id2name(model, obj, i) for i in range(getattr(model, _COUNTS[kind])))
    return [n for n in found if n]


def name_to_id(model: mujoco.MjModel, kind: str, name: str) -> int:
    """Id of the named object; raises UnknownName listing the model's objects of that kind."""
    idx = mujoco.mj_name2id(model, _OBJECT_KINDS[kind], name)
    if idx < 0:
        raise UnknownName("keyframe" if kind == "key" else kind, name, names(model, kind))
    return idx


def as_slice(indices: ArrayLike) -> slice | np.ndarray:
    """The indices as a slice where they are consecutive and ascending (numpy then views instead of
    copying), else as an integer array."""
    idx = [int(i) for i in np.asarray(indices).ravel()]
    consecutive = idx == list(range(idx[0], idx[0] + len(idx)))
    return slice(idx[0], idx[-1] + 1) if consecutive else np.array(idx)


def _movable(model: mujoco.MjModel) -> tuple[int, ...]:
    return tuple(j for j in range(model.njnt) if int(model.jnt_type[j]) in (_HINGE, _SLIDE))


def joint_ids(model: mujoco.MjModel, joints: Joints = None) -> tuple[int, ...]:
    """Ids of the controlled joints: the joints called `joints`, in that order, or by default every
    hinge and slide joint of the model in model order (free and ball joints, such as a loose
    object's, are never controlled).

    Raises:
        UnknownName: a name the model has no joint for (the message lists the model's joints).
        InvalidConfig: no joints, a repeated name, or a joint that is not a hinge or slide joint.
    """
    if joints is None:
        ids = _movable(model)
        if not ids:
            raise InvalidConfig("the model has no hinge or slide joints to control")
        return ids
    if isinstance(joints, str):  # a single name would otherwise be split into letters
        raise InvalidConfig(f"joints must be a sequence of joint names; got the string {joints!r}")
    names_ = tuple(joints)
    if not names_ or len(set(names_)) != len(names_):
        raise InvalidConfig(f"joints must be distinct joint names; got {names_!r}")
    ids = tuple(name_to_id(model, "joint", n) for n in names_)
    for n, j in zip(names_, ids):
        if int(model.jnt_type[j]) not in (_HINGE, _SLIDE):
            movable = ", ".join(model.joint(i).name for i in _movable(model)) or "none"
            raise InvalidConfig(
                f"joint {n!r} is a {_JOINT_TYPES[int(model.jnt_type[j])]} joint, not a hinge or slide "
                f"joint; only those can be controlled (the model's: {movable})"
            )
    return ids


def controlled_joints(model: mujoco.MjModel, joints: Joints = None) -> tuple[str, ...]:
    """Names of the controlled joints (see `joint_ids`): `joints` checked, or the model's default."""
    return tuple(model.joint(j).name for j in joint_ids(model, joints))


def arm_qpos_indices(model: mujoco.MjModel, joints: Joints = None) -> np.ndarray:
    """qpos addresses of the controlled joints (n,), in their order (see `joint_ids`)."""
    return np.array([model.jnt_qposadr[j] for j in joint_ids(model, joints)])


def arm_dof_indices(model: mujoco.MjModel, joints: Joints = None) -> np.ndarray:
    """qvel/dof addresses of the controlled joints (n,), in their order (see `joint_ids`)."""
    return np.array([model.jnt_dofadr[j] for j in joint_ids(model, joints)])


def joint_limits(model: mujoco.MjModel, joints: Joints = None) -> np.ndarray:
    """Position limits [lo, hi] of the controlled joints (n, 2) from `jnt_range`; -inf, inf where a
    joint has no limits."""
    ids = list(joint_ids(model, joints))
    limited = model.jnt_limited[ids].astype(bool)[:, None]
    return np.where(limited, model.jnt_range[ids], [-np.inf, np.inf])


def forward_kinematics(
    model: mujoco.MjModel, data: mujoco.MjData, q: ArrayLike, joints: Joints = None
) -> None:
    """Sets the controlled joints to q (n,) and updates frame poses and Jacobian quantities; no dynamics.

    Other generalised coordinates (a free box, say) keep their values in `data`. `joints` as in
    `joint_ids` (default: every hinge and slide joint; the six arm joints of the UR5e scenes).
    """
    qadr = arm_qpos_indices(model, joints)
    q = np.asarray(q, dtype=np.float64)
    if q.shape != qadr.shape or not np.all(np.isfinite(q)):
        raise ValueError(f"q must be {qadr.size} finite joint angles or positions; got {q!r}")
    data.qpos[qadr] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def site_pose(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """Pose T_ws of site `name` in the world frame, shape (4, 4)."""
    sid = name_to_id(model, "site", name)
    T = np.eye(4)
    T[:3, :3] = data.site_xmat[sid].reshape(3, 3)
    T[:3, 3] = data.site_xpos[sid]
    return T


def random_configurations(
    model: mujoco.MjModel, rng: np.random.Generator, n: int, joints: Joints = None
) -> np.ndarray:
    """n configurations of the controlled joints uniform within their limits, shape (n, joints).

    A hinge without limits is drawn in [-pi, pi]; a slide without limits has no range to draw from
    and raises InvalidConfig.
    """
    ids = joint_ids(model, joints)
    limits = joint_limits(model, joints)
    for j, (lo, hi) in zip(ids, limits):
        if not np.isfinite(lo) and int(model.jnt_type[j]) == _SLIDE:
            raise InvalidConfig(f"slide joint {model.joint(j).name!r} has no limits to draw positions from")
    limits = np.where(np.isfinite(limits), limits, [-np.pi, np.pi])
    return rng.uniform(limits[:, 0], limits[:, 1], size=(n, len(ids)))
