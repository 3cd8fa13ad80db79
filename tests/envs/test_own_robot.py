"""Your own arm in a task: a 3-joint arm written here (MJCF), its robot TOML and a task TOML, in a folder."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import tsrl
from tsrl.envs import TASK_ENV_ID

ARM_XML = """<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 0.1">
      <joint name="yaw" axis="0 0 1" range="-3 3" damping="2" armature="0.1"/>
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="upper" pos="0 0 0.05">
        <joint name="shoulder" axis="0 1 0" range="-2 2" damping="2" armature="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
        <body name="fore" pos="0.4 0 0">
          <joint name="elbow" axis="0 1 0" range="-2.5 2.5" damping="2" armature="0.1"/>
          <geom type="capsule" fromto="0 0 0 0.35 0 0" size="0.025" mass="0.5"/>
          <site name="tool" pos="0.35 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="yaw" joint="yaw" kp="100" kv="10"/>
    <position name="shoulder" joint="shoulder" kp="150" kv="15"/>
    <position name="elbow" joint="elbow" kp="100" kv="10"/>
  </actuator>
  <keyframe>
    <key name="home" qpos="0 -0.5 1.0" ctrl="0 -0.5 1.0"/>
  </keyframe>
</mujoco>
"""
ROBOT_TOML = """name = "arm3"
model = "arm.xml"
joints = ["yaw", "shoulder", "elbow"]
tcp = "tool"
home = "home"
actuators = ["yaw", "shoulder", "elbow"]
"""
TASK_TOML = """name = "Arm3Reach"
robot = "arm.toml"
scene = "arm.xml"
observation = "position(tool), positionDiff(tool, target), jointState"
episode_steps = 30

[[action.parts]]
map = "position(tool)"
step = 0.05

[goal]
map = "position(tool)"

[goal.position]
center = [0.6, 0.0, 0.3]
half_extent = [0.08, 0.08, 0.08]
"""


@pytest.fixture
def task_file(tmp_path):
    (tmp_path / "arm.xml").write_text(ARM_XML)
    (tmp_path / "arm.toml").write_text(ROBOT_TOML)
    path = tmp_path / "task.toml"
    path.write_text(TASK_TOML)
    return path


def test_a_task_on_your_own_arm_passes_the_checker_and_is_solved(task_file):
    env = gym.make(TASK_ENV_ID, task=str(task_file), max_episode_steps=30)
    check_env(env.unwrapped, skip_render_check=True)
    u = env.unwrapped
    assert u.robot.joints == ("yaw", "shoulder", "elbow") and "target" in [
        u.model.body(i).name for i in range(u.model.nbody)
    ]
    successes = 0
    for seed in range(10):
        obs, _ = env.reset(seed=seed)
        truncated = False
        while not truncated:  # straight to the goal through the task's position action
            action = np.clip((obs["desired_goal"] - obs["achieved_goal"]) / 0.05, -1.0, 1.0)
            obs, _, _, truncated, info = env.step(action)
        successes += info["is_success"]
    assert successes == 10


def test_a_wrong_name_in_the_robot_file_lists_what_the_model_has(task_file):
    robot = task_file.parent / "arm.toml"
    robot.write_text(ROBOT_TOML.replace('tcp = "tool"', 'tcp = "gripper"'))
    with pytest.raises(tsrl.TsrlError, match=r"gripper.*tool"):
        gym.make(TASK_ENV_ID, task=str(task_file))
