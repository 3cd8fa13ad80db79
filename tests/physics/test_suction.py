"""The adhesion actuator on the suction cup lifts the box only when it is switched on, on every arm."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.ik import DlsSolver
from tsrl.kinematics import forward_kinematics, name_to_id
from tsrl.robots import ROBOTS
from tsrl.taskmaps import parse_spec

#: Each arm's pick-and-place scene.
SCENES = {"ur5e": "pick_place", "panda": "panda_pick_place"}


def cup_down(model, data, joints, q0, goal):
    """Joint positions putting the TCP at `goal` (3,) with the cup pointing down, from q0."""
    task = parse_spec("position(tcp), vectorZ(tcp)", model, joints)
    forward_kinematics(model, data, q0, joints)
    result = DlsSolver(model, task, joints).solve(data, np.concatenate([goal, [0.0, 0.0, -1.0]]))
    assert result.converged
    return result.q


@pytest.mark.parametrize("robot", list(SCENES))
@pytest.mark.parametrize("suction_on", [True, False])
def test_suction_lifts_the_box_only_when_on(robot, suction_on):
    arm = ROBOTS[robot]
    model = load_model(SCENES[robot])
    n = len(arm.joints)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", arm.home))
    box = name_to_id(model, "body", "box")
    mujoco.mj_forward(model, data)
    box_xy = data.xpos[box][:2].copy()
    scratch = mujoco.MjData(model)
    scratch.qpos[:] = data.qpos
    above = cup_down(model, scratch, arm.joints, arm.home_q(model), np.array([*box_xy, 0.10]))
    contact = cup_down(model, scratch, arm.joints, above, np.array([*box_xy, 0.038]))  # 2 mm into the box top
    data.qpos[:n] = above
    suction = name_to_id(model, "actuator", arm.suction)

    def move_to(q, seconds, suction_value):
        data.ctrl[:n] = q
        data.ctrl[suction] = suction_value
        for _ in range(round(seconds / model.opt.timestep)):
            mujoco.mj_step(model, data)

    move_to(above, 0.3, 0.0)
    move_to(contact, 0.5, 1.0 if suction_on else 0.0)
    move_to(above, 0.8, 1.0 if suction_on else 0.0)
    lifted = data.xpos[box][2] > 0.07
    assert lifted == suction_on, f"box height {data.xpos[box][2]:.3f} m"
