"""Kinematics: MuJoCo forward kinematics without dynamics, and plain DH as an independent reference."""

from .dh import dh_forward, dh_transform
from .frames import (
    arm_dof_indices,
    arm_qpos_indices,
    as_slice,
    forward_kinematics,
    name_to_id,
    names,
    random_configurations,
    site_pose,
)

__all__ = (
    "arm_dof_indices",
    "arm_qpos_indices",
    "as_slice",
    "dh_forward",
    "dh_transform",
    "forward_kinematics",
    "name_to_id",
    "names",
    "random_configurations",
    "site_pose",
)
