"""Panda position servos with gravity compensation: a 5 cm TCP move settles fast, without overshoot."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.assets.panda import HOME_Q
from tsrl.kinematics import name_to_id

CONTROL_PERIOD = 0.04  # s, 25 Hz
NQ = len(HOME_Q)


@pytest.fixture(scope="module")
def panda_reach_model():
    return load_model("panda_reach")


def joint_target_for_tcp_move(model, data, q0, displacement):
    """Joint angles that move the TCP by `displacement` (3,) keeping its orientation (Gauss-Newton,
    minimum-norm steps: the seventh joint adds a redundant direction)."""
    tcp = name_to_id(model, "site", "tcp")
    data.qpos[:NQ] = q0
    mujoco.mj_kinematics(model, data)
    goal = data.site_xpos[tcp] + displacement
    q, jac = q0.copy(), np.zeros((6, model.nv))
    for _ in range(30):
        data.qpos[:NQ] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], tcp)
        error = np.concatenate([goal - data.site_xpos[tcp], np.zeros(3)])
        q = q + np.linalg.pinv(jac[:, :NQ]) @ error
    data.qpos[:NQ] = q
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site_xpos[tcp] - goal) < 1e-10
    return q, goal


def start_configurations():
    rng = np.random.default_rng(7)
    return [HOME_Q] + [HOME_Q + rng.uniform(-0.5, 0.5, NQ) for _ in range(3)]


@pytest.mark.parametrize("q0", start_configurations(), ids=["home", "near1", "near2", "near3"])
@pytest.mark.parametrize("axis", range(6), ids=["+x", "+y", "+z", "-x", "-y", "-z"])
def test_five_cm_tcp_move_settles_within_three_control_periods(panda_reach_model, q0, axis):
    model = panda_reach_model
    data = mujoco.MjData(model)
    direction = np.vstack([np.eye(3), -np.eye(3)])[axis]
    q_target, goal = joint_target_for_tcp_move(model, data, q0, 0.05 * direction)

    mujoco.mj_resetData(model, data)
    data.qpos[:NQ] = q0
    data.ctrl[:NQ] = q_target
    tcp = name_to_id(model, "site", "tcp")
    steps_per_period = round(CONTROL_PERIOD / model.opt.timestep)
    trajectory = []
    for _ in range(10 * steps_per_period):  # watch for 0.4 s
        mujoco.mj_step(model, data)
        trajectory.append(data.site_xpos[tcp].copy())
    trajectory = np.array(trajectory)
    error = np.linalg.norm(trajectory - goal, axis=1)
    overshoot = np.max((trajectory - goal) @ direction)

    settled_from = 3 * steps_per_period - 1  # end of the third control period
    assert np.all(error[settled_from:] < 1e-3), f"max error after 0.12 s: {error[settled_from:].max():.2e} m"
    assert overshoot < 2e-3


def test_gravity_compensation_holds_home_and_nearby_poses(panda_reach_model):
    model = panda_reach_model
    data = mujoco.MjData(model)
    for q in start_configurations():
        mujoco.mj_resetData(model, data)
        data.qpos[:NQ] = q
        data.ctrl[:NQ] = q
        for _ in range(500):  # one second
            mujoco.mj_step(model, data)
        np.testing.assert_allclose(data.qpos[:NQ], q, atol=1e-6)


def test_home_keyframe_is_held_still(panda_reach_model):
    model = panda_reach_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    tcp = name_to_id(model, "site", "tcp")
    mujoco.mj_forward(model, data)
    start = data.site_xpos[tcp].copy()
    for _ in range(1000):  # two seconds
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(data.qpos[:NQ], HOME_Q, atol=1e-6)
    np.testing.assert_allclose(data.site_xpos[tcp], start, atol=1e-6)
