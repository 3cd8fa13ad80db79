"""MuJoCo frames of our MJCF against plain DH forward kinematics (no MuJoCo involved)."""

import numpy as np
import pytest

from tsrl.assets.ur5e import HOME_Q, TCP_OFFSET, UR5E_DH
from tsrl.kinematics import dh_forward, dh_transform, forward_kinematics, random_configurations, site_pose


def test_flange_pose_equals_dh_at_random_configurations(ur5e, rng):
    model, data = ur5e
    for q in random_configurations(model, rng, 200):
        forward_kinematics(model, data, q)
        T_wf = site_pose(model, data, "flange")
        T_dh = dh_forward(UR5E_DH, q)
        np.testing.assert_allclose(T_wf[:3, 3], T_dh[:3, 3], atol=1e-6)
        np.testing.assert_allclose(T_wf[:3, :3], T_dh[:3, :3], atol=1e-6)


def test_tcp_is_on_the_flange_z_axis(ur5e, rng):
    model, data = ur5e
    for q in random_configurations(model, rng, 20):
        forward_kinematics(model, data, q)
        T_dh = dh_forward(UR5E_DH, q)
        expected = T_dh[:3, 3] + TCP_OFFSET * T_dh[:3, 2]
        np.testing.assert_allclose(site_pose(model, data, "tcp")[:3, 3], expected, atol=1e-9)


def test_dh_zero_pose_is_the_stretched_arm():
    # At q = 0 the UR arm lies along -x: x = a2 + a3, y = -(d4 + d6), z = d1 - d5.
    T = dh_forward(UR5E_DH, np.zeros(6))
    np.testing.assert_allclose(T[:3, 3], [-0.425 - 0.3922, -(0.1333 + 0.0996), 0.1625 - 0.0997], atol=1e-12)


def test_dh_transform_is_a_rigid_motion():
    T = dh_transform(0.3, 0.2, 0.7, -1.1)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)


def test_home_keyframe_is_home_q(ur5e):
    model, data = ur5e
    np.testing.assert_allclose(data.qpos[:6], HOME_Q)
    # At home the suction cup points straight down.
    np.testing.assert_allclose(site_pose(model, data, "tcp")[:3, 2], [0, 0, -1], atol=1e-9)


def test_forward_kinematics_does_not_step_dynamics(ur5e):
    model, data = ur5e
    time, qvel = data.time, data.qvel.copy()
    forward_kinematics(model, data, np.full(6, 0.3))
    assert data.time == time
    np.testing.assert_array_equal(data.qvel, qvel)
    np.testing.assert_allclose(data.qpos[:6], 0.3)


@pytest.mark.parametrize("bad", [np.zeros(5), np.array([0, 0, 0, 0, 0, np.nan])])
def test_forward_kinematics_rejects_bad_q(ur5e, bad):
    model, data = ur5e
    with pytest.raises(ValueError, match="6 finite joint angles"):
        forward_kinematics(model, data, bad)
