"""Every built-in scene, on either robot: the named parts tasks rely on, and the pick-and-place box."""

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model, panda, ur5e
from tsrl.kinematics import name_to_id
from tsrl.robots import ROBOTS

#: Built-in robot -> the module of its published facts.
FACTS = {"ur5e": ur5e, "panda": panda}
#: Built-in scene -> the robot it carries.
SCENE_ROBOTS = {
    "reach": "ur5e",
    "pick_place": "ur5e",
    "obstacle_reach": "ur5e",
    "panda_reach": "panda",
    "panda_pick_place": "panda",
    "panda_obstacle_reach": "panda",
}


@pytest.mark.parametrize("scene", sorted(SCENE_ROBOTS))
def test_scene_has_the_named_parts(scene):
    model = load_model(scene)
    robot = ROBOTS[SCENE_ROBOTS[scene]]
    for joint in robot.joints:
        name_to_id(model, "joint", joint)  # raises, listing the model's joints, when missing
    for actuator in (*robot.actuators, robot.suction):
        name_to_id(model, "actuator", actuator)
    for site in ("flange", robot.tcp, "target"):
        name_to_id(model, "site", site)
    for geom in ("table", "suction_cup"):
        name_to_id(model, "geom", geom)
    target = name_to_id(model, "body", "target")
    assert model.body_mocapid[target] >= 0
    assert model.body_geomnum[target] == 0  # the goal marker never collides
    name_to_id(model, "key", robot.home)


@pytest.mark.parametrize("scene", ["pick_place", "panda_pick_place"])
def test_pick_place_has_a_free_4cm_box_resting_on_the_table(scene):
    model = load_model(scene)
    robot = ROBOTS[SCENE_ROBOTS[scene]]
    box = name_to_id(model, "body", "box")
    assert int(model.jnt_type[model.body_jntadr[box]]) == int(mujoco.mjtJoint.mjJNT_FREE)
    np.testing.assert_allclose(model.geom_size[name_to_id(model, "geom", "box")], [0.02, 0.02, 0.02])
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", robot.home))
    home = data.qpos[: len(robot.joints)].copy()
    for _ in range(250):  # half a second: the box settles on the table top (z = 0)
        mujoco.mj_step(model, data)
    assert data.xpos[box][2] == pytest.approx(0.02, abs=2e-3)
    # the arm holds home meanwhile
    np.testing.assert_allclose(data.qpos[: len(robot.joints)], home, atol=1e-6)


@pytest.mark.parametrize("scene", ["reach", "panda_reach"])
def test_joint_limits_torques_and_servos(scene):
    """Each joint's range and its servo's control range are the published limits, its force range the
    published torque limits, with gravity compensation; the suction actuator pulls on the cup's body."""
    model = load_model(scene)
    robot = ROBOTS[SCENE_ROBOTS[scene]]
    facts = FACTS[robot.name]
    for i, name in enumerate(robot.joints):
        j = name_to_id(model, "joint", name)
        np.testing.assert_allclose(model.jnt_range[j], facts.JOINT_LIMITS[i])
        a = name_to_id(model, "actuator", robot.actuators[i])
        assert int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_JOINT)
        assert model.actuator_trnid[a, 0] == j
        np.testing.assert_allclose(model.actuator_ctrlrange[a], facts.JOINT_LIMITS[i])
        torque = facts.MAX_JOINT_TORQUES[i]
        np.testing.assert_allclose(model.actuator_forcerange[a], [-torque, torque])
        assert model.jnt_actgravcomp[j]
    suction = name_to_id(model, "actuator", robot.suction)
    assert int(model.actuator_trntype[suction]) == int(mujoco.mjtTrn.mjTRN_BODY)
    assert model.actuator_trnid[suction, 0] == name_to_id(model, "body", "suction_cup")
