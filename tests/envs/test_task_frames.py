"""envs/task_frames.py: `tcp` and `base` in specs are the robot's on any model; a task in the base frame
gives the same observations wherever the whole scene stands and however it is turned about z."""

from __future__ import annotations

import dataclasses
import importlib.util
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tsrl.assets import scene_path
from tsrl.envs.base import TaskEnv
from tsrl.envs.tasks import load_task
from tsrl.exceptions import InvalidConfig

EXAMPLES = Path(__file__).parents[2] / "examples" / "robots"
PICK_BODY = """
    <body name="box" pos="-0.5 -0.15 0.02"><freejoint name="box"/>
      <geom name="box" type="box" size="0.02 0.02 0.02" mass="0.1" contype="1" conaffinity="3"
            friction="1 0.005 0.0001"/></body>
    <body name="target" mocap="true" pos="-0.5 0.1 0.2" quat="0 0.7071067811865476 0.7071067811865476 0">
      <site name="target" type="sphere" size="0.015" group="1"/></body>"""


def _moved_scene(tmp_path: Path, pos: str, quat: str) -> Path:
    """The pick-and-place scene with the robot, table, box and marker all moved and turned about z.

    MjSpec.to_xml writes 6 significant digits: the frame's pose is exact for these tests' values
    (a turn of 180 deg is quat 0 0 0 1), about 1e-6 off otherwise."""
    path = tmp_path / "moved.xml"
    path.write_text(
        f"""<mujoco model="moved">
  <include file="{scene_path("ur5e")}"/>
  <include file="{scene_path("pick_place").parent / "table.xml"}"/>
  <worldbody><frame pos="{pos}" quat="{quat}">{PICK_BODY}</frame></worldbody>
</mujoco>"""
    )
    # the included robot and table stand at the origin: move them into the same frame
    spec = mujoco.MjSpec.from_file(str(path))
    frame = spec.worldbody.frames[0]
    for element in [spec.body("base"), *(spec.geom(n) for n in ("floor", "table"))]:
        element.set_frame(frame)
    path.write_text(spec.to_xml())
    return path


TURN_50 = f"{np.cos(np.radians(25)):.17g} 0 0 {np.sin(np.radians(25)):.17g}"


@pytest.mark.parametrize(
    ("pos", "quat", "atol"),
    [("0.7 -1.2 0.3", "0 0 0 1", 1e-9), ("-2.5 0.4 0", TURN_50, 1e-5)],
    ids=["turned-180", "turned-50"],
)
def test_a_base_frame_task_sees_the_same_wherever_the_scene_stands(tmp_path, pos, quat, atol):
    base_task = dataclasses.replace(load_task("UR5ePickPlace-v0"), frame="base")
    # the scene where it stands, written the same way (MjSpec.to_xml rounds the robot's own numbers)
    (tmp_path / "here").mkdir()
    here = _moved_scene(tmp_path / "here", "0 0 0", "1 0 0 0")
    reference = TaskEnv(dataclasses.replace(base_task, scene=str(here)), obs="pick_phi_plus")
    moved = TaskEnv(
        dataclasses.replace(base_task, scene=str(_moved_scene(tmp_path, pos, quat))), obs="pick_phi_plus"
    )
    # every observation, goal and reward is the same, relative to the base (that the scene file really
    # stands elsewhere: the next test)
    rng = np.random.default_rng(0)
    for seed in range(3):
        a, _ = reference.reset(seed=seed)
        b, _ = moved.reset(seed=seed)
        for key in a:
            np.testing.assert_allclose(b[key], a[key], atol=atol, err_msg=key)
        for _ in range(15):
            action = rng.uniform(-1, 1, 4)
            a, ra, *_ = reference.step(action)
            b, rb, *_ = moved.step(action)
            for key in a:
                np.testing.assert_allclose(b[key], a[key], atol=100 * atol, err_msg=key)
            assert ra == rb


def test_the_moved_scene_is_moved_before_the_base_frame_takes_it_back(tmp_path):
    """Without frame = "base" the same moved scene gives world positions shifted by the frame."""
    task = load_task("UR5ePickPlace-v0")
    moved = TaskEnv(dataclasses.replace(task, scene=str(_moved_scene(tmp_path, "0.7 -1.2 0.3", "0 0 0 1"))))
    data = mujoco.MjData(moved.model)
    mujoco.mj_kinematics(moved.model, data)
    np.testing.assert_allclose(data.xpos[moved.model.body("base").id], [0.7, -1.2, 0.3], atol=1e-12)


def test_a_tilted_base_is_refused_for_a_base_frame_task(tmp_path):
    path = _moved_scene(tmp_path, "0 0 0", f"{np.cos(0.05):.17g} {np.sin(0.05):.17g} 0 0")  # 5.7 deg about x
    task = dataclasses.replace(load_task("UR5ePickPlace-v0"), frame="base", scene=str(path))
    with pytest.raises(InvalidConfig, match="base is tilted"):
        TaskEnv(task)


@pytest.mark.skipif(importlib.util.find_spec("gymnasium_robotics") is None, reason="needs gymnasium-robotics")
def test_presets_and_the_taskspace_action_follow_the_robot_on_the_fetch_arm():
    with pytest.warns(UserWarning):
        env = TaskEnv(EXAMPLES / "fetch_reach.toml", obs="fs1", action="taskspace")
    obs, _ = env.reset(seed=0)
    m, d = env.model, env.data
    grip, tcp = m.site("robot0:grip").id, m.site("tcp").id
    np.testing.assert_array_equal(d.site_xpos[tcp], d.site_xpos[grip])
    np.testing.assert_array_equal(obs["observation"][:3], d.site_xpos[grip])
    base = m.site("base").id  # added at the arm's base body
    first_joint_body = m.jnt_bodyid[m.joint("robot0:shoulder_pan_joint").id]
    assert m.site_bodyid[base] == m.body_parentid[first_joint_body]
    obs, *_ = env.step(np.zeros(3))
    assert np.isfinite(obs["observation"]).all()


def test_a_frame_called_tcp_that_is_not_the_robots_tcp_is_one_line_naming_the_robot_file(tmp_path):
    robot = tmp_path / "ur5e_flange.toml"
    robot.write_text(
        f'name = "ur5e_flange"\nmodel = "{scene_path("ur5e")}"\n'
        'joints = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]\n'
        'tcp = "flange"\nhome = "home"\n'
        "reach_low = [-1.0, -1.0, 0.0]\nreach_high = [1.0, 1.0, 1.0]\n"  # the goal box inside it: the frame is what fails
    )
    task = dataclasses.replace(load_task("UR5eReach-v0"), robot=str(robot), scene=str(scene_path("reach")))
    with pytest.raises(InvalidConfig) as err:
        TaskEnv(task)
    message = str(err.value)
    assert "\n" not in message and "ur5e_flange.toml" in message and "another frame named 'tcp'" in message
