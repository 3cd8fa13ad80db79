"""The `taskspace` presets keep the TCP target in the robot's box (tsrl.taskspace_box): the built-in
arms' table box (unchanged: the rollout fingerprints hold it), a robot file's reach_low/reach_high,
else `tsrl robot check`'s reach box around the TCP at home; a goal box outside it is one line."""

from __future__ import annotations

import numpy as np
import pytest
from own_task import write_task

from tsrl.envs.actions import action_mode, preset
from tsrl.envs.tasks import load_task
from tsrl.exceptions import InvalidConfig
from tsrl.robot_check import check_robot
from tsrl.robot_model import load_robot_model
from tsrl.robots import ROBOTS, TABLE_REACH_HIGH, TABLE_REACH_LOW, load_robot
from tsrl.taskspace_box import DEFAULT_HALF_EXTENT, tcp_at_home


def preset_task(folder, center, half_extent, robot_extra: str = ""):
    """The own arm's task (tests/own_task.py) with the `taskspace` preset and a goal box of position(tcp)."""
    task = write_task(folder)
    robot = folder / "arm.toml"
    robot.write_text(robot.read_text() + robot_extra)
    text = task.read_text().split("[[action.parts]]")[0]
    task.write_text(
        text.replace('observation = "', 'action = "taskspace"\nobservation = "')
        + f'[goal]\nmap = "position(tcp)"\n\n[goal.position]\ncenter = {[float(c) for c in center]}\n'
        f"half_extent = {list(half_extent)}\n"
    )
    return task


@pytest.fixture
def arm_home(tmp_path):
    write_task(tmp_path / "probe")
    robot = load_robot(tmp_path / "probe" / "arm.toml")
    model, _ = load_robot_model(robot, "arm.toml")
    return tcp_at_home(model, robot)


def test_the_built_in_arms_keep_the_table_box():
    for name in ("UR5eReach-v0", "PandaPush-v0", "UR5ePickPlace-v0"):
        (part,) = load_task(name).action_spec.parts
        assert (part.map, part.low, part.high) == ("position(tcp)", TABLE_REACH_LOW, TABLE_REACH_HIGH)
    assert all(r.reach_low == TABLE_REACH_LOW and r.reach_high == TABLE_REACH_HIGH for r in ROBOTS.values())


def test_a_robot_file_without_a_box_gets_the_reach_box_robot_check_verifies(tmp_path, arm_home):
    task = load_task(preset_task(tmp_path / "a", arm_home, [0.1, 0.1, 0.1]))
    (part,) = task.action_spec.parts
    np.testing.assert_allclose(part.low, arm_home - DEFAULT_HALF_EXTENT, atol=1e-12)
    np.testing.assert_allclose(part.high, arm_home + DEFAULT_HALF_EXTENT, atol=1e-12)
    assert action_mode(task.action_spec) == "taskspace"
    report = check_robot(str(tmp_path / "a" / "arm.toml"))
    text = "\n".join(report.lines)
    assert f"reach box: centre [{', '.join(f'{c:.3f}' for c in arm_home)}], half-extent [0.150" in text
    assert "(the default reach box around home)" in text
    # The old UR5e box would have refused this goal box (it lies at positive x, the arm's side).
    assert arm_home[0] > TABLE_REACH_HIGH[0]


def test_a_goal_box_outside_the_robots_box_is_one_line_naming_where_the_box_comes_from(tmp_path, arm_home):
    with pytest.raises(InvalidConfig) as err:
        load_task(preset_task(tmp_path / "b", arm_home, [0.2, 0.1, 0.1]))
    message = str(err.value)
    assert "leaves the workspace the TCP target may reach" in message and "\n" not in message
    assert "the robot's reach_low/reach_high, else `tsrl robot check`'s reach box" in message


def test_a_robot_files_declared_box_bounds_the_preset(tmp_path, arm_home):
    declared = "reach_low = [0.1, -0.5, 0.0]\nreach_high = [0.9, 0.5, 0.8]\n"
    task = load_task(preset_task(tmp_path / "c", arm_home, [0.2, 0.1, 0.1], declared))  # now inside
    (part,) = task.action_spec.parts
    assert part.low == (0.1, -0.5, 0.0) and part.high == (0.9, 0.5, 0.8)
    assert "(the robot's reach_low/reach_high)" in "\n".join(
        check_robot(str(tmp_path / "c" / "arm.toml")).lines
    )
    for bad in ("reach_low = [0.1, -0.5, 0.0]\n", "reach_low = [0.9, 0, 0]\nreach_high = [0.1, 1, 1]\n"):
        with pytest.raises(InvalidConfig, match=r"reach_low .*accepted: both or neither, 3 finite values"):
            load_task(preset_task(tmp_path / "d", arm_home, [0.1, 0.1, 0.1], bad))


def test_action_mode_names_a_preset_whatever_its_box():
    spec = preset("taskspace", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))
    assert action_mode(spec) == "taskspace"
    assert action_mode(preset("taskspace_orient", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))) == "taskspace_orient"
