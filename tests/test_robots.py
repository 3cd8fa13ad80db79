"""Robot descriptions: the built-in UR5e, a robot from TOML with an MJCF or URDF file, clear errors."""

from __future__ import annotations

import textwrap

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.assets.ur5e import HOME_Q, JOINT_NAMES
from tsrl.exceptions import InvalidConfig, ModelLoadError, UnknownName
from tsrl.kinematics import controlled_joints, forward_kinematics
from tsrl.robots import ROBOTS, Robot, load_robot
from tsrl.taskmaps import parse_spec

URDF = """<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"/>
  <link name="upper">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <link name="lower">
    <inertial><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="shoulder" type="revolute">
    <parent link="base"/><child link="upper"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="upper"/><child link="lower"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-2" upper="2" effort="10" velocity="1"/>
  </joint>
</robot>
"""


def test_built_in_ur5e_matches_its_scenes():
    robot = ROBOTS["ur5e"]
    assert load_robot("ur5e") is robot
    model = robot.load_model()
    np.testing.assert_array_equal(robot.home_q(model), HOME_Q)
    for scene in ("reach", "pick_place"):  # the scenes' default joints are the robot's
        scene_model = load_model(scene)
        robot.validate(scene_model)
        assert controlled_joints(scene_model) == robot.joints == JOINT_NAMES


def test_robot_from_toml_with_an_mjcf_file(tmp_path):
    from test_any_robot import PLANAR_ARM

    (tmp_path / "arm.xml").write_text(PLANAR_ARM)
    (tmp_path / "arm.toml").write_text(
        textwrap.dedent(
            """
            name = "planar4"
            model = "arm.xml"
            joints = ["j1", "j2", "j3", "j4"]
            tcp = "tool"
            home = "rest"
            actuators = ["a1", "a2", "a3", "a4"]
            """
        )
    )
    robot = load_robot(tmp_path / "arm.toml")
    assert robot.model == str(tmp_path / "arm.xml") and robot.joints == ("j1", "j2", "j3", "j4")
    model = robot.load_model()
    np.testing.assert_array_equal(robot.home_q(model), [0.4, 0.8, 1.0, 0.5])


def test_robot_from_a_urdf_file_with_a_body_as_tcp(tmp_path):
    (tmp_path / "two_link.urdf").write_text(URDF)
    path = str(tmp_path / "two_link.urdf")
    with pytest.raises(UnknownName, match="unknown frame 'tip'; the model's frames: lower, upper, world"):
        Robot(name="two_link", model=path, joints=("shoulder", "elbow"), tcp="tip").load_model()
    robot = Robot(name="two_link", model=path, joints=("shoulder", "elbow"), tcp="lower")
    model = robot.load_model()
    assert controlled_joints(model) == robot.joints
    data = mujoco.MjData(model)
    forward_kinematics(model, data, [np.pi / 2, 0.3])
    np.testing.assert_allclose(
        parse_spec("position(lower)", model)(model, data).y, [0.4, 0.0, 0.0], atol=1e-12
    )


def test_bad_descriptions_are_named(tmp_path):
    with pytest.raises(
        UnknownName,
        match=r"unknown robot 'ur10'; built-in robots: .*ur5e, ur5e_gripper \(or a robot's .toml file\)",
    ):
        load_robot("ur10")
    (tmp_path / "bad.toml").write_text(
        'name = "x"\nmodel = "ur5e"\njoints = ["elbow"]\ntcp = "tcp"\ncamera = 1\n'
    )
    with pytest.raises(InvalidConfig, match="bad.toml: unknown key 'camera'; accepted: name, model, joints"):
        load_robot(tmp_path / "bad.toml")
    (tmp_path / "short.toml").write_text('name = "x"\nmodel = "ur5e"\n')
    with pytest.raises(InvalidConfig, match="short.toml: missing keys 'joints', 'tcp'"):
        load_robot(tmp_path / "short.toml")
    with pytest.raises(InvalidConfig, match="2 actuators for 1 joints"):
        Robot(name="x", model="ur5e", joints=("elbow",), tcp="tcp", actuators=("elbow", "wrist_1"))
    with pytest.raises(ModelLoadError, match="no URDF file"):
        Robot(name="x", model=str(tmp_path / "missing.urdf"), joints=("a",), tcp="t").load_model()
    robot = Robot(
        name="x", model="ur5e", joints=JOINT_NAMES, tcp="tcp", actuators=JOINT_NAMES, suction="vacuum"
    )
    with pytest.raises(UnknownName, match="unknown actuator 'vacuum'; the model's actuators: elbow"):
        robot.load_model()
