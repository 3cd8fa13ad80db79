"""The IK on the 7-joint Panda: full pose solves of reachable targets, and the null-space posture term
(the redundant joint moves the elbow while the TCP pose holds)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.ik import DlsSolver, IKOptions
from tsrl.kinematics import forward_kinematics, joint_limits, random_configurations
from tsrl.robots import ROBOTS
from tsrl.taskmaps import parse_spec

PANDA = ROBOTS["panda"]
POSE = "position(tcp), quaternion(tcp)"


@pytest.fixture(scope="module")
def panda():
    model = load_model("panda_reach")
    return model, mujoco.MjData(model)


def test_full_pose_solves_reach_random_reachable_targets_within_the_limits(panda, rng):
    model, data = panda
    pose = parse_spec(POSE, model, PANDA.joints)
    home = PANDA.home_q(model)
    solver = DlsSolver(model, pose, PANDA.joints, IKOptions(posture=tuple(home)))
    limits = joint_limits(model, PANDA.joints)
    for q in random_configurations(model, rng, 20, PANDA.joints):
        forward_kinematics(model, data, q, PANDA.joints)
        target = pose(model, data).y  # reachable by construction
        forward_kinematics(model, data, home, PANDA.joints)
        result = solver.solve(data, target)
        assert result.converged, f"error {result.error_norm:.2e}"
        assert np.all(result.q >= limits[:, 0]) and np.all(result.q <= limits[:, 1])
        forward_kinematics(model, data, result.q, PANDA.joints)
        np.testing.assert_allclose(pose(model, data).y[:3], target[:3], atol=1e-4)


def test_posture_term_moves_the_elbow_without_moving_the_tcp_pose(panda):
    model, data = panda
    pose = parse_spec(POSE, model, PANDA.joints)
    home = PANDA.home_q(model)
    start = home + np.array([0.4, 0.2, -0.5, 0.1, 0.3, 0.0, 0.0])
    forward_kinematics(model, data, start, PANDA.joints)
    target = pose(model, data).y
    solver = DlsSolver(model, pose, PANDA.joints, IKOptions(posture=tuple(home), posture_gain=0.2))
    q = start.copy()
    for _ in range(200):
        forward_kinematics(model, data, q, PANDA.joints)
        q, _ = solver.step(q, pose(model, data), target)
    forward_kinematics(model, data, q, PANDA.joints)
    np.testing.assert_allclose(pose(model, data).y, target, atol=1e-5)
    elbow = data.body("link4").xpos.copy()
    forward_kinematics(model, data, start, PANDA.joints)
    assert np.linalg.norm(elbow - data.body("link4").xpos) > 0.01  # the elbow moved (by 1.3 cm)
    assert np.linalg.norm(q - home) < np.linalg.norm(start - home)  # towards the rest posture
