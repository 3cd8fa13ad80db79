"""Franka Emika Panda facts and the names used in our MJCF: modified DH table, joints, limits, inertias,
sites, home pose, base placement and the reach goal box.

Every number's source is listed in assets/panda/README.md.
"""

from __future__ import annotations

import numpy as np

#: Modified (Craig) DH parameters (a_{i-1} [m], d_i [m], alpha_{i-1} [rad]) for joints 1..7, as
#: Franka's documentation lists them: T_{i-1,i} = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(q_i) Tz(d_i).
PANDA_MDH: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.333, 0.0),
    (0.0, 0.0, -np.pi / 2),
    (0.0, 0.316, np.pi / 2),
    (0.0825, 0.0, np.pi / 2),
    (-0.0825, 0.384, -np.pi / 2),
    (0.0, 0.0, np.pi / 2),
    (0.088, 0.0, np.pi / 2),
)

#: The fixed flange row (a_7, d_F, alpha_7) of Franka's table, theta = 0: the flange frame is DH frame
#: 7 moved 0.107 m along its z axis, same orientation.
FLANGE_MDH: tuple[float, float, float] = (0.0, 0.107, 0.0)

#: Pose T_w0 of DH frame 0 (the base) in the world: at the origin, turned by pi about z, so that the
#: arm faces -x (over the table, where the UR5e works too).
BASE_POSE = np.array(
    [
        [-1.0, 0.0, 0.0, 0.0],
        [0.0, -1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
)

#: Link masses [kg], links 1..7 (Gaz et al. 2019).
LINK_MASSES: tuple[float, ...] = (4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522)

#: Centres of mass [m] of links 1..7, each in its own modified-DH frame i (Gaz et al. 2019). The z
#: coordinate of link 1 does not enter the dynamics (link 1 only turns about z) and is 0 there.
LINK_COMS: tuple[tuple[float, float, float], ...] = (
    (3.875e-03, 2.081e-03, 0.0),
    (-3.141e-03, -2.872e-02, 3.495e-03),
    (2.7518e-02, 3.9252e-02, -6.6502e-02),
    (-5.317e-02, 1.04419e-01, 2.7454e-02),
    (-1.1953e-02, 4.1065e-02, -3.8437e-02),
    (6.0149e-02, -1.4117e-02, -1.0517e-02),
    (1.0517e-02, -4.252e-03, 6.1597e-02),
)

#: Inertia tensors [kg m^2] of links 1..7 about their centres of mass, in axes parallel to DH frame i,
#: as (Ixx, Ixy, Ixz, Iyy, Iyz, Izz) (Gaz et al. 2019).
LINK_INERTIAS: tuple[tuple[float, float, float, float, float, float], ...] = (
    (7.0337e-01, -1.3900e-04, 6.7720e-03, 7.0661e-01, 1.9169e-02, 9.1170e-03),
    (7.9620e-03, -3.9250e-03, 1.0254e-02, 2.8110e-02, 7.0400e-04, 2.5995e-02),
    (3.7242e-02, -4.7610e-03, -1.1396e-02, 3.6155e-02, -1.2805e-02, 1.0830e-02),
    (2.5853e-02, 7.7960e-03, -1.3320e-03, 1.9552e-02, 8.6410e-03, 2.8323e-02),
    (3.5549e-02, -2.1170e-03, -4.0370e-03, 2.9474e-02, 2.2900e-04, 8.6270e-03),
    (1.9640e-03, 1.0900e-04, -1.1580e-03, 4.3540e-03, 3.4100e-04, 5.4330e-03),
    (1.2516e-02, -4.2800e-04, -1.1960e-03, 1.0027e-02, -7.4100e-04, 4.8150e-03),
)

JOINT_NAMES: tuple[str, ...] = tuple(f"joint{i}" for i in range(1, 8))
BODY_NAMES: tuple[str, ...] = tuple(f"link{i}" for i in range(1, 8))
TCP_SITE = "tcp"
SUCTION_ACTUATOR = "suction"
HOME_KEY = "home"

#: Home configuration [rad]: the arm in the vertical plane through the base (q1 = q3 = q5 = 0), the cup
#: pointing straight down (q6 = q2 - q4) and turned as the UR5e's at its home (q7 = pi/2: the TCP's x
#: axis along world +y), so the same target orientation serves both robots.
HOME_Q = np.array([0.0, -0.3, 0.0, -2.3, 0.0, 2.0, np.pi / 2])

#: TCP position [m] at HOME_Q in the world: the centre of the reach goal box (half-extent 0.15 m),
#: which the TCP reaches everywhere with the cup pointing down (tests/assets/test_panda_model.py).
HOME_TCP = np.array([-0.4569332, 0.0, 0.3974834])
GOAL_HALF_EXTENT = 0.15

#: Joint position limits [rad], rows (min, max), joints 1..7 (Franka).
JOINT_LIMITS = np.array(
    [
        [-2.8973, 2.8973],
        [-1.7628, 1.7628],
        [-2.8973, 2.8973],
        [-3.0718, -0.0698],
        [-2.8973, 2.8973],
        [-0.0175, 3.7525],
        [-2.8973, 2.8973],
    ]
)

#: Maximum joint speeds [rad/s], joints 1..7 (Franka); MuJoCo does not enforce them.
MAX_JOINT_SPEEDS = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])

#: Maximum joint torques [N m], joints 1..7 (Franka).
MAX_JOINT_TORQUES = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])

#: Suction cup tip (site `tcp`) along the flange z axis [m] (the same cup as the UR5e's).
TCP_OFFSET = 0.07

# -- The Franka Hand (panda/hand*.xml, on the Panda and the UR5e; sources in assets/panda/README.md) -----

#: Mass [kg] of the hand with its fingers (Franka).
HAND_MASS = 0.73
#: Mass [kg] of each finger (our choice; Franka publishes the hand's mass only).
FINGER_MASS = 0.02
#: Travel [m] of each finger from closed (0) to open (Franka: 80 mm stroke, 40 mm per finger).
FINGER_TRAVEL = 0.04
#: Largest opening width [m] between the fingers' inner faces.
MAX_WIDTH = 2 * FINGER_TRAVEL
#: Rated continuous grasp force [N] (Franka); the servo's force limit on each finger.
GRASP_FORCE = 70.0
#: Peak grasp force [N] (Franka), for short times; not modelled (the servo holds the rated force).
MAX_GRASP_FORCE = 140.0
#: TCP (between the fingertips) along the flange z axis [m] (Franka's end-effector frame).
HAND_TCP_OFFSET = 0.1034
#: The hand's turn about the flange z axis [rad] (Franka's mounting).
HAND_YAW = -np.pi / 4
#: The finger joints along the hand's z axis [m] from the flange (franka_description).
FINGER_OFFSET = 0.0584
#: The hand's finger joints (slide joints, 0 = closed) and the servo of the opening width.
FINGER_JOINTS: tuple[str, ...] = ("finger_left", "finger_right")
GRIPPER_ACTUATOR = "gripper"

#: Home configuration [rad] of the arm with the hand: HOME_Q with joint 7 turned by pi/4 more, which
#: undoes the hand's -pi/4, so the TCP frame is the suction Panda's at home (x along world +y, z down);
#: the fingers open along world x. Keyframe `home` of panda_gripper.xml (fingers open, 40 mm each).
GRIPPER_HOME_Q = np.array([0.0, -0.3, 0.0, -2.3, 0.0, 2.0, 3 * np.pi / 4])
#: TCP position [m] at GRIPPER_HOME_Q: HOME_TCP moved down by HAND_TCP_OFFSET - TCP_OFFSET.
GRIPPER_HOME_TCP = np.array([-0.4569332, 0.0, 0.3640834])
