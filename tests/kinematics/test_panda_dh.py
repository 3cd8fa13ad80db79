"""The Panda MJCF's frames against plain modified-DH forward kinematics (no MuJoCo involved)."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.assets.panda import (
    BASE_POSE,
    FLANGE_MDH,
    HOME_Q,
    HOME_TCP,
    JOINT_LIMITS,
    PANDA_MDH,
    TCP_OFFSET,
)
from tsrl.kinematics import site_pose
from tsrl.kinematics.dh import modified_dh_forward, modified_dh_transform


@pytest.fixture(scope="module")
def panda():
    model = load_model("panda_reach")
    return model, mujoco.MjData(model)


def set_q(model, data, q):
    data.qpos[:7] = q
    mujoco.mj_kinematics(model, data)


def dh_flange(q):
    """T_wf: world <- base (fixed placement) <- DH frame 7 <- flange (0.107 m along z7)."""
    return BASE_POSE @ modified_dh_forward(PANDA_MDH, q) @ modified_dh_transform(*FLANGE_MDH, theta=0.0)


def test_flange_pose_equals_modified_dh_at_random_configurations(panda, rng):
    model, data = panda
    worst = 0.0
    for q in rng.uniform(JOINT_LIMITS[:, 0], JOINT_LIMITS[:, 1], (200, 7)):
        set_q(model, data, q)
        T_wf = site_pose(model, data, "flange")
        T_dh = dh_flange(q)
        np.testing.assert_allclose(T_wf[:3, 3], T_dh[:3, 3], atol=1e-6)
        np.testing.assert_allclose(T_wf[:3, :3], T_dh[:3, :3], atol=1e-6)
        worst = max(worst, np.abs(T_wf - T_dh).max())
    assert worst < 1e-6


def test_tcp_is_on_the_flange_z_axis(panda, rng):
    model, data = panda
    for q in rng.uniform(JOINT_LIMITS[:, 0], JOINT_LIMITS[:, 1], (20, 7)):
        set_q(model, data, q)
        T_dh = dh_flange(q)
        expected = T_dh[:3, 3] + TCP_OFFSET * T_dh[:3, 2]
        np.testing.assert_allclose(site_pose(model, data, "tcp")[:3, 3], expected, atol=1e-9)


def test_modified_dh_zero_pose_is_the_upright_arm():
    # At q = 0 the Panda stands upright and the flange points down, offset by a_7 along x:
    # x = a_3 + a_4 + a_6 = 0.0825 - 0.0825 + 0.088, z = d_1 + d_3 + d_5 - d_F (Franka's figure).
    T = modified_dh_forward(PANDA_MDH, np.zeros(7)) @ modified_dh_transform(*FLANGE_MDH, theta=0.0)
    np.testing.assert_allclose(T[:3, 3], [0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107], atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)


def test_modified_dh_transform_is_a_rigid_motion_in_craigs_order():
    a, d, alpha, theta = 0.3, 0.2, 0.7, -1.1
    T = modified_dh_transform(a, d, alpha, theta)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    # Rx(alpha) Tx(a) Rz(theta) Tz(d), built from elementary motions.
    c, s = np.cos(alpha), np.sin(alpha)
    rx = np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])
    c, s = np.cos(theta), np.sin(theta)
    rz = np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    tx, tz = np.eye(4), np.eye(4)
    tx[0, 3], tz[2, 3] = a, d
    np.testing.assert_allclose(T, rx @ tx @ rz @ tz, atol=1e-12)


def test_modified_dh_forward_rejects_a_wrong_number_of_angles():
    with pytest.raises(ValueError, match=r"expected \(7,\)"):
        modified_dh_forward(PANDA_MDH, np.zeros(6))


def test_home_keyframe_is_home_q_with_the_cup_down(panda):
    model, _ = panda
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, "home"))
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.qpos[:7], HOME_Q)
    np.testing.assert_allclose(data.ctrl[:7], HOME_Q)
    T_wt = site_pose(model, data, "tcp")
    np.testing.assert_allclose(T_wt[:3, 2], [0, 0, -1], atol=1e-9)  # the cup points straight down
    np.testing.assert_allclose(T_wt[:3, 0], [0, 1, 0], atol=1e-9)  # turned as the UR5e's TCP at home
    np.testing.assert_allclose(T_wt[:3, 3], HOME_TCP, atol=1e-6)
    np.testing.assert_allclose(T_wt[:3, 3], dh_flange(HOME_Q)[:3, 3] - [0, 0, TCP_OFFSET], atol=1e-9)
