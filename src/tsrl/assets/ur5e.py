"""UR5e facts and the names used in our MJCF: DH table, joints, sites, home pose, limits.

Every number's source is listed in assets/ur5e/README.md.
"""

from __future__ import annotations

import numpy as np

#: Standard DH parameters (a [m], d [m], alpha [rad]) for joints 1..6 (Universal Robots).
UR5E_DH: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.1625, np.pi / 2),
    (-0.425, 0.0, 0.0),
    (-0.3922, 0.0, 0.0),
    (0.0, 0.1333, np.pi / 2),
    (0.0, 0.0997, -np.pi / 2),
    (0.0, 0.0996, 0.0),
)

#: Link masses [kg], links 1..6 (Universal Robots).
LINK_MASSES: tuple[float, ...] = (3.761, 8.058, 2.846, 1.37, 1.3, 0.365)

#: Centres of mass [m] of links 1..6, each in its own DH frame i (Universal Robots).
LINK_COMS_DH: tuple[tuple[float, float, float], ...] = (
    (0.0, -0.02561, 0.00193),
    (0.2125, 0.0, 0.11336),
    (0.15, 0.0, 0.0265),
    (0.0, -0.0018, 0.01634),
    (0.0, 0.0018, 0.01634),
    (0.0, 0.0, -0.001159),
)

JOINT_NAMES: tuple[str, ...] = (
    "shoulder_pan",
    "shoulder_lift",
    "elbow",
    "wrist_1",
    "wrist_2",
    "wrist_3",
)
BODY_NAMES: tuple[str, ...] = (
    "shoulder_link",
    "upper_arm_link",
    "forearm_link",
    "wrist_1_link",
    "wrist_2_link",
    "wrist_3_link",
)
TCP_SITE = "tcp"
SUCTION_ACTUATOR = "suction"
HOME_KEY = "home"

#: Home configuration [rad].
HOME_Q = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])

#: Joint position limits [rad]: +-2 pi, elbow +-pi.
JOINT_LIMITS = np.array([[-2 * np.pi, 2 * np.pi]] * 2 + [[-np.pi, np.pi]] + [[-2 * np.pi, 2 * np.pi]] * 3)

#: Maximum joint speed [rad/s] (180 deg/s on every joint).
MAX_JOINT_SPEED = np.pi

#: Maximum joint torques [N m]: size-3 joints (base, shoulder, elbow), size-1 joints (wrists).
MAX_JOINT_TORQUES = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])

#: Suction cup tip (site `tcp`) along the flange z axis [m].
TCP_OFFSET = 0.07

# -- The UR5e with the Franka Hand (ur5e/ur5e_gripper.xml; the hand's facts: tsrl.assets.panda) -----------

#: The hand's turn about the flange z axis [rad]: none, so the fingers open along the flange's y axis
#: (world +x at HOME_Q) and the TCP frame at home is the suction UR5e's (x along world +y, z down).
GRIPPER_HAND_YAW = 0.0
#: TCP position [m] at HOME_Q with the hand (keyframe `home` of ur5e_gripper.xml, fingers open): the cup's
#: tip moved down by the hand's TCP offset minus the cup's, 0.1034 m - 0.07 m.
GRIPPER_HOME_TCP = np.array([-0.4919, -0.1333, 0.3845])
