"""Off-screen rendering shows the robot."""

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import tsrl  # noqa: F401  (registers the environments)
from tsrl.assets.ur5e import HOME_Q
from tsrl.kinematics import forward_kinematics
from tsrl.rendering import SceneRenderer, render_rgb


def test_rendered_image_shows_the_robot(ur5e):
    model, data = ur5e
    image = render_rgb(model, data, width=320, height=240)
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8
    assert image.std() > 10  # not blank, not uniform
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50


def test_the_image_changes_when_the_arm_moves(ur5e):
    model, data = ur5e
    with SceneRenderer(model, width=320, height=240) as renderer:
        home = renderer.render(data)
        forward_kinematics(model, data, HOME_Q + np.array([1.0, 0.4, -0.5, 0.0, 0.0, 0.0]))
        moved = renderer.render(data)
    changed = np.any(home != moved, axis=-1).mean()
    assert changed > 0.01, f"only {changed:.2%} of the pixels changed"


def test_pick_place_scene_renders(tmp_path):
    from tsrl.assets import load_model

    model = load_model("pick_place")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    assert render_rgb(model, data, 160, 120).std() > 10


def test_the_env_camera_frames_the_task_workspace_and_takes_a_model_camera():
    env = gym.make("tsrl/PandaPickPlace-v0", render_mode="rgb_array", width=64, height=48).unwrapped
    env.reset(seed=0)
    camera = env._camera_view()
    p = env.task.goal.position
    # the free camera looks at the middle of the goal box (lifted goals included) and the TCP at home
    assert abs(camera.lookat[0] - p.center[0]) < 0.2 and abs(camera.lookat[1] - p.center[1]) < 0.2
    assert env.render().shape == (48, 64, 3)
    env.close()
    named = gym.make("tsrl/UR5eReach-v0", render_mode="rgb_array", camera="nope").unwrapped
    named.reset(seed=0)
    with pytest.raises(Exception, match="nope"):  # an unknown camera name is named in the error
        named.render()
