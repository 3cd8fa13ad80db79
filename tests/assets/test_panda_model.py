"""Our Panda MJCF and scenes: names, published facts, the reachable goal box, the suction cup."""

import itertools

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.assets.panda import (
    BODY_NAMES,
    GOAL_HALF_EXTENT,
    HOME_Q,
    HOME_TCP,
    JOINT_LIMITS,
    JOINT_NAMES,
    LINK_COMS,
    LINK_INERTIAS,
    LINK_MASSES,
    MAX_JOINT_TORQUES,
)
from tsrl.kinematics import name_to_id

OBJ = mujoco.mjtObj
NQ = len(JOINT_NAMES)


@pytest.fixture(scope="module")
def panda_reach_model():
    return load_model("panda_reach")


def cup_down_ik(model, data, goal, q0=HOME_Q, iterations=200):
    """Joint angles putting the TCP at `goal` with the cup pointing down: damped least squares on
    position and z-axis alignment, a null-space pull towards q0, steps clipped to the joint limits."""
    tcp = name_to_id(model, "site", "tcp")
    low, high = model.jnt_range[:NQ, 0] + 1e-6, model.jnt_range[:NQ, 1] - 1e-6
    q, jac = np.array(q0, dtype=float), np.zeros((6, model.nv))
    for _ in range(iterations):
        data.qpos[:NQ] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], tcp)
        z = data.site_xmat[tcp].reshape(3, 3)[:, 2]
        error = np.concatenate([goal - data.site_xpos[tcp], np.cross(z, [0, 0, -1])])
        J = jac[:, :NQ]
        dq = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(6), error)
        dq += (np.eye(NQ) - np.linalg.pinv(J) @ J) @ (0.1 * (q0 - q))
        q = np.clip(q + dq, low, high)
    data.qpos[:NQ] = q
    mujoco.mj_kinematics(model, data)
    return q


def test_link_masses_centres_of_mass_and_inertias_are_gaz_et_al():
    model = load_model("panda")
    for i, body in enumerate(BODY_NAMES):
        b = name_to_id(model, "body", body)
        assert model.body_mass[b] == pytest.approx(LINK_MASSES[i])
        # Body i is DH frame i, in which Gaz et al. give the centre of mass and the inertia axes.
        np.testing.assert_allclose(model.body_ipos[b], LINK_COMS[i], atol=1e-12)
        xx, xy, xz, yy, yz, zz = LINK_INERTIAS[i]
        published = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.body_iquat[b])
        R = R.reshape(3, 3)
        np.testing.assert_allclose(R @ np.diag(model.body_inertia[b]) @ R.T, published, atol=1e-9)


def test_gravity_compensation_fits_in_the_torque_limits_everywhere(rng):
    model = load_model("panda")
    data = mujoco.MjData(model)
    for q in rng.uniform(JOINT_LIMITS[:, 0], JOINT_LIMITS[:, 1], (200, NQ)):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        assert np.all(np.abs(data.qfrc_gravcomp[:NQ]) < 0.7 * MAX_JOINT_TORQUES)


def test_random_goals_in_the_box_are_reached_cup_down(panda_reach_model, rng):
    model = panda_reach_model
    data = mujoco.MjData(model)
    tcp = name_to_id(model, "site", "tcp")
    corners = [HOME_TCP + GOAL_HALF_EXTENT * np.array(s) for s in itertools.product((-1, 1), repeat=3)]
    goals = corners + list(HOME_TCP + rng.uniform(-GOAL_HALF_EXTENT, GOAL_HALF_EXTENT, (100, 3)))
    for goal in goals:
        q = cup_down_ik(model, data, goal)
        assert np.all(q >= JOINT_LIMITS[:, 0]) and np.all(q <= JOINT_LIMITS[:, 1])
        np.testing.assert_allclose(data.site_xpos[tcp], goal, atol=1e-6, err_msg=f"goal {goal}")
        np.testing.assert_allclose(data.site_xmat[tcp].reshape(3, 3)[:, 2], [0, 0, -1], atol=1e-6)
