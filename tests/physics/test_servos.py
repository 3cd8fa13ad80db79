"""Position servos with gravity compensation, on every built-in arm: a 5 cm TCP move settles fast,
without overshoot, and any pose near home is held still."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model, panda, ur5e
from tsrl.kinematics import name_to_id

CONTROL_PERIOD = 0.04  # s, 25 Hz
#: Each built-in arm: its reach scene and home configuration (the arm's joints come first in qpos).
ARMS = {"ur5e": ("reach", ur5e.HOME_Q), "panda": ("panda_reach", panda.HOME_Q)}


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request):
    scene, home = ARMS[request.param]
    return load_model(scene), home


def joint_target_for_tcp_move(model, data, q0, displacement):
    """Joint angles that move the TCP by `displacement` (3,) keeping its orientation (Gauss-Newton,
    minimum-norm steps, which a seventh joint makes redundant)."""
    n = len(q0)
    tcp = name_to_id(model, "site", "tcp")
    data.qpos[:n] = q0
    mujoco.mj_kinematics(model, data)
    goal = data.site_xpos[tcp] + displacement
    q, jac = q0.copy(), np.zeros((6, model.nv))
    for _ in range(30):
        data.qpos[:n] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], tcp)
        error = np.concatenate([goal - data.site_xpos[tcp], np.zeros(3)])
        q = q + np.linalg.pinv(jac[:, :n]) @ error
    data.qpos[:n] = q
    mujoco.mj_kinematics(model, data)
    assert np.linalg.norm(data.site_xpos[tcp] - goal) < 1e-10
    return q, goal


def start_configurations(home):
    rng = np.random.default_rng(7)
    return [home] + [home + rng.uniform(-0.5, 0.5, len(home)) for _ in range(3)]


@pytest.mark.parametrize("start", range(4), ids=["home", "near1", "near2", "near3"])
@pytest.mark.parametrize("axis", range(6), ids=["+x", "+y", "+z", "-x", "-y", "-z"])
def test_five_cm_tcp_move_settles_within_three_control_periods(arm, start, axis):
    model, home = arm
    q0, n = start_configurations(home)[start], len(home)
    data = mujoco.MjData(model)
    direction = np.vstack([np.eye(3), -np.eye(3)])[axis]
    q_target, goal = joint_target_for_tcp_move(model, data, q0, 0.05 * direction)

    mujoco.mj_resetData(model, data)
    data.qpos[:n] = q0
    data.ctrl[:n] = q_target
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


def test_gravity_compensation_holds_home_and_nearby_poses(arm):
    model, home = arm
    data = mujoco.MjData(model)
    for q in start_configurations(home):
        mujoco.mj_resetData(model, data)
        data.qpos[: len(q)] = q
        data.ctrl[: len(q)] = q
        for _ in range(500):  # one second
            mujoco.mj_step(model, data)
        np.testing.assert_allclose(data.qpos[: len(q)], q, atol=1e-6)


def test_home_keyframe_is_held_still(arm):
    model, home = arm
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    tcp = name_to_id(model, "site", "tcp")
    mujoco.mj_forward(model, data)
    start = data.site_xpos[tcp].copy()
    for _ in range(1000):  # two seconds
        mujoco.mj_step(model, data)
    np.testing.assert_allclose(data.qpos[: len(home)], home, atol=1e-6)
    np.testing.assert_allclose(data.site_xpos[tcp], start, atol=1e-6)
