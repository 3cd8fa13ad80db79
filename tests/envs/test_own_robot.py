"""Your own arm in a task: a 3-joint arm written here (MJCF), its robot TOML and a task TOML, in a folder;
the same arm as models often come (no servos, no keyframe), which tsrl completes; and Gymnasium-Robotics'
Fetch arm as its package ships it (examples/robots/)."""

from __future__ import annotations

import importlib.util
import math
import warnings
from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import stable_baselines3.common.env_checker as sb3_checker
from gymnasium.utils.env_checker import check_env
from own_task import ARM_XML, ROBOT_TOML, TASK_TOML, write_task

import tsrl
from tsrl.envs import TASK_ENV_ID
from tsrl.robot_model import RobotNotice
from tsrl.settling import settle


@pytest.fixture
def task_file(tmp_path):
    return write_task(tmp_path)


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


# -- a model as many come: no actuators, no keyframe --------------------------------------------------
BARE_XML = ARM_XML.split("  <actuator>")[0] + "</mujoco>\n"
BARE_ROBOT_TOML = """name = "arm3"
model = "arm.xml"
joints = ["yaw", "shoulder", "elbow"]
tcp = "tool"
home = [0.0, -0.5, 1.0]
"""
REPO = Path(__file__).resolve().parents[2]
FETCH_REACH = REPO / "examples" / "robots" / "fetch_reach.toml"
needs_gymnasium_robotics = pytest.mark.skipif(
    importlib.util.find_spec("gymnasium_robotics") is None,
    reason="Gymnasium-Robotics is not installed (pip install gymnasium-robotics==1.4.2; the dev extra has it)",
)


@pytest.fixture
def bare_task_file(task_file):
    (task_file.parent / "arm.xml").write_text(BARE_XML)
    (task_file.parent / "arm.toml").write_text(BARE_ROBOT_TOML)
    return task_file


def make_quietly(task, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotNotice)
        return gym.make(TASK_ENV_ID, task=str(task), **kwargs)


def solve_episodes(env, seeds) -> int:
    """Successes of the straight-to-the-goal policy through the task's position action."""
    successes = 0
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        truncated = False
        while not truncated:
            action = np.clip((obs["desired_goal"] - obs["achieved_goal"]) / 0.05, -1.0, 1.0)
            obs, _, _, truncated, info = env.step(action)
        successes += info["is_success"]
    return successes


def meets_settling_target(env) -> bool:
    u = env.unwrapped
    key = u.bound_robot.home_key
    result = settle(u.model, u.robot.joints, u.robot.tcp, u.robot.home_q(u.model), key)
    assert result.ok, result.summary()
    return result.ok


def test_an_arm_without_servos_gets_them_and_is_solved(bare_task_file):
    env = make_quietly(bare_task_file, max_episode_steps=30)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_checker.check_env(env.unwrapped, warn=True)
    u = env.unwrapped
    assert [u.model.actuator(i).name for i in range(u.model.nu)] == [
        "yaw:servo",
        "shoulder:servo",
        "elbow:servo",
    ]
    assert u.model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    env.reset(seed=0)
    np.testing.assert_array_equal(u.data.qpos[:3], [0.0, -0.5, 1.0])  # the robot file's home
    assert meets_settling_target(env)
    assert solve_episodes(env, range(10)) == 10


def test_servos_on_some_joints_but_not_all_name_the_robot_file(bare_task_file):
    (bare_task_file.parent / "arm.xml").write_text(
        BARE_XML.replace(
            "</mujoco>", '<actuator><position name="p" joint="yaw" kp="50"/></actuator></mujoco>'
        )
    )
    with pytest.raises(tsrl.TsrlError) as err:
        make_quietly(bare_task_file)
    robot_file = bare_task_file.parent / "arm.toml"
    assert str(err.value) == (  # the task file, then the robot file and its key
        f"{bare_task_file}: {robot_file}: actuators: the model has position servos on yaw but not on shoulder, elbow; "
        "accepted: a servo on every controlled joint, or on none (tsrl adds them)"
    )


def test_the_default_camera_finds_an_arm_far_from_the_origin(bare_task_file):
    """Segmentation: the share of pixels that show the arm's geoms, with the default camera and with
    the one fixed on the UR5e's workspace that rendering used before."""
    (bare_task_file.parent / "arm.xml").write_text(
        BARE_XML.replace('<body name="base" pos="0 0 0.1">', '<body name="base" pos="3 -2 0.1">')
    )
    text = bare_task_file.read_text().replace("center = [0.6, 0.0, 0.3]", "center = [3.6, -2.0, 0.3]")
    bare_task_file.write_text(text)
    env = make_quietly(bare_task_file, render_mode="rgb_array")
    env.reset(seed=0)
    from tsrl.rendering import default_camera

    model, data = env.unwrapped.model, env.unwrapped.data
    arm = {model.geom(g).id for g in range(model.ngeom) if model.geom_bodyid[g] > 0}
    old = mujoco.MjvCamera()
    old.lookat[:], old.distance, old.azimuth, old.elevation = (-0.35, -0.05, 0.25), 1.9, 135.0, -25.0
    shares = []
    with mujoco.Renderer(model, 240, 320) as renderer:
        renderer.enable_segmentation_rendering()
        for camera in (default_camera(model), old):
            renderer.update_scene(data, camera=camera)
            ids = renderer.render()[..., 0]
            shares.append(np.isin(ids, list(arm)).mean())
    assert shares[0] > 0.02 and shares[1] == 0.0
    assert env.render().std() > 10


@needs_gymnasium_robotics
def test_fetch_reach_passes_the_checkers_meets_the_settling_target_and_is_solved():
    """Gymnasium-Robotics' Fetch MJCF, unmodified, with the ten-line robot file of examples/robots/."""
    with pytest.warns(
        RobotNotice, match="hinge joints robot0:upperarm_roll_joint, robot0:forearm_roll_joint"
    ):
        env = gym.make(TASK_ENV_ID, task=str(FETCH_REACH), max_episode_steps=50)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_checker.check_env(env.unwrapped, warn=True)
    u = env.unwrapped
    assert u.model.neq == 0  # the mocap weld dropped
    assert meets_settling_target(env)
    # at rest with zero actions: gravity compensated, nothing pins or pushes the gripper
    obs, _ = env.reset(seed=0)
    start = obs["achieved_goal"].copy()
    for _ in range(10):
        obs, *_ = env.step(np.zeros(3))
    assert np.linalg.norm(obs["achieved_goal"] - start) < 1e-3
    assert solve_episodes(env, range(5)) == 5
    assert math.isclose(u.task.control_dt, 0.04)


def test_a_model_inside_an_installed_package_is_named_with_pkg(task_file):
    """tsrl is itself an installed package: its UR5e file by pkg://, from a robot file and a task's scene."""
    folder = task_file.parent
    (folder / "ur5e.toml").write_text(
        'name = "ur5e_pkg"\nmodel = "pkg://tsrl/assets/ur5e/ur5e.xml"\n'
        'joints = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]\n'
        'tcp = "tcp"\nhome = "home"\n'
    )
    text = TASK_TOML.replace('robot = "arm.toml"', 'robot = "ur5e.toml"')
    text = text.replace('scene = "arm.xml"', 'scene = "pkg://tsrl/assets/scenes/reach.xml"')
    text = text.replace("(tool", "(tcp").replace("center = [0.6, 0.0, 0.3]", "center = [-0.49, -0.13, 0.42]")
    task_file.write_text(text)
    env = gym.make(TASK_ENV_ID, task=str(task_file), max_episode_steps=30)
    assert env.unwrapped.robot.model == "pkg://tsrl/assets/ur5e/ur5e.xml"
    assert solve_episodes(env, range(3)) == 3
    task_file.write_text(
        text.replace("pkg://tsrl/assets/scenes/reach.xml", "pkg://no_such_package/reach.xml")
    )
    with pytest.raises(tsrl.TsrlError) as err:
        gym.make(TASK_ENV_ID, task=str(task_file))
    assert str(err.value) == (
        f"{task_file}: scene = 'pkg://no_such_package/reach.xml': no installed package 'no_such_package' "
        "(pip install it first)"
    )
    task_file.write_text(text.replace("scenes/reach.xml", "scenes/nope.xml"))
    with pytest.raises(
        tsrl.TsrlError, match="scene = 'pkg://tsrl/assets/scenes/nope.xml': package 'tsrl' has no file"
    ):
        gym.make(TASK_ENV_ID, task=str(task_file))
