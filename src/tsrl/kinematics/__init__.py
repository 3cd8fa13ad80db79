"""Kinematics: MuJoCo forward kinematics without dynamics, and plain DH as an independent reference."""

from .dh import dh_forward, dh_transform
from .frames import (
    Joints,
    arm_dof_indices,
    arm_qpos_indices,
    as_slice,
    controlled_joints,
    forward_kinematics,
    joint_ids,
    joint_limits,
    name_to_id,
    names,
    random_configurations,
    site_pose,
)

__all__ = (
    "Joints",
    "arm_dof_indices",
    "arm_qpos_indices",
    "as_slice",
    "controlled_joints",
    "dh_forward",
    "dh_transform",
    "forward_kinematics",
    "joint_ids",
    "joint_limits",
    "name_to_id",
    "names",
    "random_configurations",
    "site_pose",
)
