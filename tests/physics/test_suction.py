"""The adhesion actuator on the suction cup lifts the box only when it is switched on."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.assets.ur5e import HOME_Q
from tsrl.kinematics import forward_kinematics, name_to_id


def tcp_ik(model, data, q0, goal):
    """Joint angles putting the TCP at `goal` with the cup pointing down (Gauss-Newton on 5 rows)."""
    tcp = name_to_id(model, "site", "tcp")
    q, jac = q0.copy(), np.zeros((6, model.nv))
    for _ in range(50):
        forward_kinematics(model, data, q)
        mujoco.mj_jacSite(model, data, jac[:3], jac[3:], tcp)
        z = data.site_xmat[tcp].reshape(3, 3)[:, 2]
        # rows: position error, and z-axis alignment with -world z (cross product, 2 useful rows)
        error = np.concatenate([goal - data.site_xpos[tcp], np.cross(z, [0, 0, -1])])
        q = q + np.linalg.lstsq(jac[:, :6], error, rcond=None)[0]
    return q


@pytest.mark.parametrize("suction_on", [True, False])
def test_suction_lifts_the_box_only_when_on(suction_on):
    model = load_model("pick_place")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    box = name_to_id(model, "body", "box")
    mujoco.mj_forward(model, data)
    box_xy = data.xpos[box][:2].copy()
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = data.qpos
    above = tcp_ik(model, scratch, HOME_Q, np.array([*box_xy, 0.10]))
    contact = tcp_ik(model, scratch, above, np.array([*box_xy, 0.038]))  # 2 mm into the box top
    data.qpos[:6] = above
    suction = name_to_id(model, "actuator", "suction")

    def move_to(q, seconds, suction_value):
        data.ctrl[:6] = q
        data.ctrl[suction] = suction_value
        for _ in range(round(seconds / model.opt.timestep)):
            mujoco.mj_step(model, data)

    move_to(above, 0.3, 0.0)
    move_to(contact, 0.5, 1.0 if suction_on else 0.0)
    move_to(above, 0.8, 1.0 if suction_on else 0.0)
    lifted = data.xpos[box][2] > 0.07
    assert lifted == suction_on, f"box height {data.xpos[box][2]:.3f} m"
