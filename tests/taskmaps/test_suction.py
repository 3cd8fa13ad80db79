"""suction(actuator): [on, holding] of an adhesion suction cup, against MuJoCo's own state."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents.demonstrators import record_demos
from tsrl.assets import load_model
from tsrl.exceptions import InvalidConfig, UnknownName
from tsrl.taskmaps import FrameCache, Suction, parse_spec

PICK = "tsrl/UR5ePickPlace-v0"


def test_on_follows_the_command_and_holding_means_touching_the_box():
    """Along scripted pick-and-place episodes: on = the suction command just applied; holding = on and
    the cup's and the box's geoms touch (mj_geomDistance <= 0, the margins are 0), computed apart."""
    demos = record_demos(PICK, 2, obs="position(box), suction(suction)")
    env = gym.make(PICK, obs="position(box)").unwrapped
    cup, box = env.model.geom("suction_cup").id, env.model.geom("box").id
    assert env.model.geom_margin[[cup, box]].tolist() == [0.0, 0.0]
    fromto = np.zeros(6)
    for i in range(demos.n_episodes):
        env.reset(seed=int(demos.seeds[i]))
        y = demos.observation[i, :, 3:]
        np.testing.assert_array_equal(y[0], [0.0, 0.0])
        for t, action in enumerate(demos.actions[i]):
            env.step(action)
            on = float(action[-1] > 0)
            touching = mujoco.mj_geomDistance(env.model, env.data, cup, box, 0.01, fromto) <= 0.0
            np.testing.assert_array_equal(y[t + 1], [on, float(on and touching)], err_msg=f"step {t}")
        lifted = demos.observation[i, :, 2] > demos.observation[i, 0, 2] + 0.02
        assert lifted.any() and y[lifted, 1].all()  # the box is up only while the cup holds it
    env.close()


def test_jacobian_is_zero_and_finite_differences_agree(ur5e):
    model, data = ur5e
    task_map = parse_spec("suction(suction)", model)
    data.ctrl[model.actuator("suction").id] = 1.0
    mujoco.mj_forward(model, data)
    y, J = task_map(model, data)
    assert J.shape == (2, model.nv) and not J.any()
    for k in range(model.nv):  # away from the box nothing switches: y is constant in q
        data.qpos[k] += 1e-6
        mujoco.mj_forward(model, data)
        np.testing.assert_array_equal(task_map(model, data).y, y)
        data.qpos[k] -= 1e-6


def test_bad_actuators_are_one_clear_error(ur5e):
    model, _ = ur5e
    with pytest.raises(UnknownName, match="unknown actuator 'cup'; the model's actuators: .*suction"):
        Suction(model, "cup")
    with pytest.raises(InvalidConfig, match="'elbow' is not an adhesion actuator"):
        Suction(model, "elbow")


def test_maps_reading_contacts_share_one_collision_pass_per_evaluation():
    """A stack of suction and accumulatedCollisions gives each map's own value; the cache runs
    mj_collision once per update (a second `collide` before the next update keeps the contacts)."""
    model = load_model("pick_place")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    box = model.jnt_qposadr[model.body("box").jntadr[0]]
    cup_tip = data.site_xpos[model.site("tcp").id]
    data.qpos[box : box + 3] = cup_tip - [0.0, 0.0, 0.019]  # the box pressed 1 mm into the cup
    data.ctrl[model.actuator("suction").id] = 1.0
    mujoco.mj_forward(model, data)
    stacked = parse_spec("suction(suction), accumulatedCollisions", model)(model, data)
    alone = [parse_spec(spec, model)(model, data) for spec in ("suction(suction)", "accumulatedCollisions")]
    np.testing.assert_array_equal(stacked.y, np.concatenate([v.y for v in alone]))
    np.testing.assert_array_equal(stacked.J, np.concatenate([v.J for v in alone]))
    assert stacked.y[1] == 1.0 and stacked.y[2] > 0.0  # holding, and penetrating

    cache = FrameCache(model, [])
    cache.update(data)
    cache.collide()
    touching = data.ncon
    data.qpos[box + 2] += 0.2  # lift the box off the cup; kinematics only, data.contact untouched
    mujoco.mj_kinematics(model, data)
    cache.collide()  # the same update: no new collision pass, the contacts stay
    assert data.ncon == touching
    cache.update(data)
    cache.collide()
    assert data.ncon < touching
