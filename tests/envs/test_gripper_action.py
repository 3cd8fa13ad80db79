"""The gripper's action dimension: a width target (the default) or open/close (`gripper_open_close`), on
the gripper pick-and-place in real MuJoCo physics."""

import gymnasium as gym
import numpy as np
import pytest

import tsrl  # noqa: F401
from tsrl.envs import TASK_ENV_ID, load_task
from tsrl.envs.actions import action_mode
from tsrl.envs.layout import layout
from tsrl.exceptions import InvalidConfig

GRIPPER_TOML = load_task("PandaPickPlaceGripper-v0").source


def _task_file(tmp_path, open_close: bool):
    text = GRIPPER_TOML.read_text()
    if open_close:
        text = text.replace("gripper = true ", "gripper = true\ngripper_open_close = true ", 1)
    path = tmp_path / ("open_close.toml" if open_close else "width.toml")
    path.write_text(text)
    return path


def _servo_targets(env, commands):
    """The gripper servo's target [m] after one step with each last-dimension command (TCP still)."""
    g = env.bound_robot.gripper_ctrl
    targets = []
    for c in commands:
        env.step(np.array([0.0, 0.0, 0.0, c], dtype=np.float32))
        targets.append(float(env.data.ctrl[g]))
    return targets, env.model.actuator_ctrlrange[g]


def test_open_close_sets_the_range_ends_and_width_interpolates(tmp_path):
    commands = [0.5, -0.25, 0.0, 1e-3, -1.0, 1.0]
    widths, (low, high) = _servo_targets(_reset(_task_file(tmp_path, False)), commands)
    switched, _ = _servo_targets(_reset(_task_file(tmp_path, True)), commands)
    np.testing.assert_allclose(widths, [low + (c + 1) / 2 * (high - low) for c in commands], atol=1e-7)
    assert switched == [high, low, low, high, low, high]


def test_open_close_moves_the_fingers_as_the_width_range_ends_do(tmp_path):
    """Commands of either sign and any size move the fingers as full width commands of that sign do."""
    switched, width = _reset(_task_file(tmp_path, True)), _reset(_task_file(tmp_path, False))
    part = switched.observation_structure["gripperWidth(gripper)"]
    seen = []
    for command in [0.1] * 4 + [-0.3] * 14 + [0.7] * 4:
        a = np.array([0.0, 0.0, 0.0, command], dtype=np.float32)
        obs, *_ = switched.step(a)
        a[-1] = np.sign(command)
        expected, *_ = width.step(a)
        np.testing.assert_array_equal(obs["observation"], expected["observation"])
        seen.append(obs["observation"][part][0])
    assert max(seen) > 0.07 and min(seen) < 0.01  # the fingers did open and close


def test_open_close_survives_a_built_in_action_override(tmp_path):
    task = load_task(_task_file(tmp_path, True))
    spec = task.with_overrides(action="taskspace").action_spec
    assert spec.gripper and spec.gripper_open_close
    assert action_mode(spec) == "taskspace"
    assert dict(layout(_reset(_task_file(tmp_path, True))).action)["gripper"].startswith("open (0.08 m)")


def test_open_close_without_a_gripper_dimension_is_refused(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(GRIPPER_TOML.read_text().replace("gripper = true ", "gripper_open_close = true ", 1))
    with pytest.raises(InvalidConfig, match=r"bad\.toml.*gripper_open_close.*accepted: .*gripper dimension"):
        load_task(path)


def _reset(path):
    env = gym.make(TASK_ENV_ID, task=str(path)).unwrapped
    env.reset(seed=0)
    return env
