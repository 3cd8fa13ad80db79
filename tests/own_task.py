"""A task on an arm written here, in a folder of its own as a user keeps one: the arm's MJCF (with a
camera `top` looking down on it), its robot file and the task file (its own observation and action),
for the tests of task files (tests/envs/test_own_robot.py, `tsrl train --task FILE`, `tsrl render
--camera`)."""

from __future__ import annotations

from pathlib import Path

ARM_XML = """<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <camera name="top" pos="0.4 0 2.0"/>
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
#: Its own observation (not fs1) and action (a table: the run's action is `task`); 30-step episodes.
OBSERVATION = "position(tool), positionDiff(tool, target), jointState"
EPISODE_STEPS = 30
TASK_TOML = f"""name = "Arm3Reach"
robot = "arm.toml"
scene = "arm.xml"
observation = "{OBSERVATION}"
episode_steps = {EPISODE_STEPS}

[[action.parts]]
map = "position(tool)"
step = 0.05

[goal]
map = "position(tool)"

[goal.position]
center = [0.6, 0.0, 0.3]
half_extent = [0.08, 0.08, 0.08]
"""


def write_task(folder: Path) -> Path:
    """Writes arm.xml, arm.toml and task.toml into `folder`; returns the task file."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "arm.xml").write_text(ARM_XML)
    (folder / "arm.toml").write_text(ROBOT_TOML)
    path = folder / "task.toml"
    path.write_text(TASK_TOML)
    return path
