"""Bad input: NaN/inf actions rejected before the simulator, clipping, unknown names, blow-ups."""

import gymnasium as gym
import numpy as np
import pytest

import tsrl  # noqa: F401
from tsrl.exceptions import InvalidAction, InvalidConfig, UnknownTaskMap


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_action_raises_and_leaves_the_state_unchanged(bad):
    env = gym.make("tsrl/UR5eReach-v0").unwrapped
    env.reset(seed=0)
    env.step(np.array([0.3, -0.2, 0.1]))
    qpos, qvel, ctrl, time = env.data.qpos.copy(), env.data.qvel.copy(), env.data.ctrl.copy(), env.data.time
    with pytest.raises(InvalidAction, match="NaN or inf"):
        env.step(np.array([0.1, bad, 0.0]))
    np.testing.assert_array_equal(env.data.qpos, qpos)
    np.testing.assert_array_equal(env.data.qvel, qvel)
    np.testing.assert_array_equal(env.data.ctrl, ctrl)
    assert env.data.time == time


def test_wrong_action_shape_raises():
    env = gym.make("tsrl/UR5eReach-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(InvalidAction, match=r"expected \(3,\)"):
        env.step(np.zeros(4))


def test_actions_outside_the_box_are_clipped():
    a, b = gym.make("tsrl/UR5eReach-v0"), gym.make("tsrl/UR5eReach-v0")
    a.reset(seed=0)
    b.reset(seed=0)
    for _ in range(3):
        obs_big, *_ = a.step(np.array([5.0, -7.0, 30.0]))
        obs_one, *_ = b.step(np.array([1.0, -1.0, 1.0]))
    np.testing.assert_array_equal(obs_big["observation"], obs_one["observation"])


def test_unknown_preset_or_map_lists_the_accepted_names():
    with pytest.raises(UnknownTaskMap, match=r"'fs9'.*baseline.*fs0.*fs1.*fs2.*position.*simple"):
        gym.make("tsrl/UR5eReach-v0", obs="fs9")


def test_unknown_action_mode_lists_the_accepted_modes():
    with pytest.raises(InvalidConfig, match=r"'cartesian'.*taskspace, taskspace_orient, joint"):
        gym.make("tsrl/UR5eReach-v0", action="cartesian")


def test_physics_blow_up_ends_the_episode_with_a_flag():
    env = gym.make("tsrl/UR5eReach-v0", obs="fs1").unwrapped
    obs, _ = env.reset(seed=0)
    env.data.qvel[:] = 1e30  # a state no physics can integrate
    obs, _, _, truncated, info = env.step(np.zeros(3))
    assert truncated and info["physics_unstable"]
    assert all(np.all(np.isfinite(v)) for v in obs.values())


def _peg_task_with_hole(tmp_path, inward):
    """PandaPegInsert-v0 with its fixture's four walls moved `inward` [m] towards the hole's centre: a
    copy of the scenes and the Panda's files (MJCF resolves nested includes from the main file's folder)."""
    import re
    import shutil
    from pathlib import Path

    from tsrl.envs import load_task

    task = load_task("PandaPegInsert-v0")
    assets = Path(task.source).parents[2] / "assets"
    for folder in ("scenes", "panda"):
        shutil.copytree(assets / folder, tmp_path / folder, dirs_exist_ok=True)  # afresh each call
    parts = tmp_path / "scenes" / "peg_insert.xml"

    def moved(m):
        x, y = float(m.group(1)), float(m.group(2))
        return f'pos="{x - np.sign(x) * inward:.4f} {y - np.sign(y) * inward:.4f} 0.015"'

    parts.write_text(re.sub(r'pos="(-?[0-9.]+) (-?[0-9.]+) 0\.015"', moved, parts.read_text()))
    text = Path(task.source).read_text()
    text = text.replace('scene = "panda_gripper_peg"', 'scene = "scenes/panda_gripper_peg.xml"')
    (tmp_path / "peg.toml").write_text(text)
    return load_task(tmp_path / "peg.toml")


def test_a_hole_smaller_than_the_peg_is_one_line_naming_the_fixture(tmp_path):
    from tsrl.envs import TaskEnv

    TaskEnv(_peg_task_with_hole(tmp_path, 0.001)).close()  # 1 mm of clearance left: accepted
    with pytest.raises(
        InvalidConfig,
        match=r"peg\.toml: \[\[fixtures\]\] body 'fixture': 'peg' at its goal penetrates it by 1\.0 mm",
    ) as err:
        TaskEnv(_peg_task_with_hole(tmp_path, 0.003))  # the hole 2 mm narrower than the peg
    assert "\n" not in str(err.value) and "accepted: a fixture the object at its goal clears" in str(
        err.value
    )
