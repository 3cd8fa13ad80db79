"""`tsrl render --camera NAME` and `tsrl show --camera NAME`: pictures from a camera of the model, each
compared with MuJoCo's own rendering from that camera; an unknown camera is one line, exit code 2."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from cli_runner import TINY, run_tsrl
from own_task import EPISODE_STEPS, write_task
from PIL import Image

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents.evaluation import eval_seeds
from tsrl.envs import TASK_ENV_ID

SIZE = (64, 48)


@pytest.fixture(scope="module")
def task_file(tmp_path_factory) -> Path:
    return write_task(tmp_path_factory.mktemp("my_task"))


@pytest.fixture(scope="module")
def run_dir(task_file, tmp_path_factory) -> Path:
    """A run on the task whose model has a camera `top` (one checkpoint, no update: a policy to show)."""
    out = tmp_path_factory.mktemp("runs")
    result = run_tsrl(
        "train", "--task", str(task_file), "--out-dir", str(out), *TINY, "--total-timesteps", "60",
        "--checkpoint-freq", "60",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    (run,) = out.iterdir()
    return run


def first_frame(path: Path) -> np.ndarray:
    with Image.open(path) as gif:
        return np.asarray(gif.convert("RGB"), dtype=np.float64)


def test_render_takes_a_camera_of_the_model(run_dir, task_file, tmp_path):
    frames = {}
    for camera in ("top", None):
        out = tmp_path / f"{camera}.gif"
        given = ["--camera", camera] if camera is not None else []
        size = [str(n) for n in SIZE]
        result = run_tsrl(
            "render", str(run_dir), "--out", str(out), "--episodes", "1", "--size", *size, *given
        )
        assert result.returncode == 0, result.stderr
        frames[camera] = first_frame(out)
    # MuJoCo's own picture from the camera `top` of the episode's first state (the run's first seed),
    # its kinematics computed here from the state's positions.
    env = gym.make(TASK_ENV_ID, task=str(task_file), max_episode_steps=EPISODE_STEPS)
    env.reset(seed=eval_seeds(0, 1)[0])
    model = env.unwrapped.model
    data = mujoco.MjData(model)
    data.qpos[:] = env.unwrapped.data.qpos
    data.mocap_pos[:] = env.unwrapped.data.mocap_pos  # the goal marker
    data.mocap_quat[:] = env.unwrapped.data.mocap_quat
    env.close()
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=SIZE[1], width=SIZE[0]) as renderer:
        renderer.update_scene(data, camera="top")
        expected = renderer.render().astype(np.float64)
    assert frames["top"].shape == expected.shape == (SIZE[1], SIZE[0], 3)
    error = np.abs(frames["top"] - expected).mean()  # a GIF's palette rounds the colours
    assert error < 3, error
    assert np.abs(frames[None] - expected).mean() > 10 * max(
        error, 1
    )  # the workspace camera sees another view


def test_render_with_an_unknown_camera_is_one_line_listing_the_models_cameras(run_dir, tmp_path):
    out = tmp_path / "v.gif"
    result = run_tsrl("render", str(run_dir), "--out", str(out), "--camera", "side")
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines() == [
        "tsrl: error: unknown camera 'side'; the model's cameras: top"
    ]
    assert not out.exists()


def test_show_takes_a_camera_of_the_model(task_file, tmp_path):
    model_file = task_file.parent / "arm.xml"
    result = run_tsrl(
        "show", "--scene", str(model_file), "--camera", "top", "--poses", "0", "--out-dir", str(tmp_path)
    )
    assert result.returncode == 0, result.stderr
    shown = np.asarray(Image.open(tmp_path / "arm_home.png").convert("RGB"))
    model = mujoco.MjModel.from_xml_path(str(model_file))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)  # home
    mujoco.mj_forward(model, data)
    with mujoco.Renderer(model, height=shown.shape[0], width=shown.shape[1]) as renderer:
        renderer.update_scene(data, camera="top")
        np.testing.assert_array_equal(shown, renderer.render())
        renderer.update_scene(data)  # MuJoCo's default free camera: another picture
        assert np.abs(shown.astype(int) - renderer.render()).mean() > 10


def test_show_with_an_unknown_camera_is_one_line_and_writes_nothing(tmp_path):
    out = tmp_path / "show"
    result = run_tsrl("show", "--camera", "side", "--out-dir", str(out))  # the reach scene has no camera
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines() == [
        "tsrl: error: unknown camera 'side'; the model's cameras: none"
    ]
    assert not out.exists()
