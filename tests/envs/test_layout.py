"""envs/layout.py: tasks whose policies are interchangeable are accepted, each kind of mismatch refused."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import pytest

from tsrl.envs.base import TaskEnv
from tsrl.envs.layout import check_same_layout, layout
from tsrl.envs.tasks import load_task
from tsrl.exceptions import InvalidConfig


@pytest.mark.parametrize(
    "task",
    [
        "Reach-v0",
        "PickPlace-v0",
        "PoseReach-v0",
        "ObstacleReach-v1",
        "Push-v0",
        "BaseReach-v0",
        "BasePickPlace-v0",
    ],
)
def test_the_two_arms_share_the_layout_of_each_built_in_task(task):
    ur5e, panda = (layout(gym.make(f"tsrl/{arm}{task}").unwrapped) for arm in ("UR5e", "Panda"))
    check_same_layout(ur5e, panda, "UR5e", "Panda")
    assert ur5e == panda


def _refusal(trained: TaskEnv, other: TaskEnv) -> str:
    with pytest.raises(InvalidConfig) as err:
        check_same_layout(layout(trained), layout(other), "RUN", "OTHER")
    message = str(err.value)
    assert "\n" not in message and message.startswith("OTHER does not match the layout of RUN")
    return message


def test_each_kind_of_mismatch_is_named():
    reach = TaskEnv("UR5eReach-v0", obs="fs1")
    assert "observation row 4 is nothing there, velocity(positionDiff(tcp, target)) (3 values)" in _refusal(
        reach, TaskEnv("UR5eReach-v0", obs="fs0, velocity(position(tcp))")
    )
    assert "observation row 0 is position(box) (3 values) there, position(tcp) (3 values)" in _refusal(
        TaskEnv("UR5eReach-v0", obs="baseline"),
        TaskEnv("UR5ePickPlace-v0", obs="position(box), velocity(position(tcp))"),
    )
    # joint-space policies do not move between arms of different joint counts
    assert "jointState (7 values) there, jointState (6 values)" in _refusal(
        TaskEnv("UR5eReach-v0", obs="fs1, jointState"), TaskEnv("PandaReach-v0", obs="fs1, jointState")
    )
    assert "action part 0 is joint steps (7 joints" in _refusal(
        TaskEnv("UR5eReach-v0", action="joint"), TaskEnv("PandaReach-v0", action="joint")
    )
    assert "action part 1 is scalarProductXX(world, tcp)" in _refusal(
        reach, TaskEnv("UR5eReach-v0", obs="fs1", action="taskspace_orient")
    )
    assert "goal row 0 is position(box)" in _refusal(reach, TaskEnv("UR5ePickPlace-v0", obs="fs1"))
    assert "action part 2 is nothing there, suction (on above 0)" in _refusal(
        TaskEnv("UR5ePickPlace-v0", obs="fs1"), TaskEnv("UR5ePush-v0", obs="fs1")
    )
    slow = dataclasses.replace(load_task("UR5eReach-v0"), control_dt=0.08)
    assert "control_dt 0.08 s there, 0.04 s" in _refusal(TaskEnv("UR5eReach-v0"), TaskEnv(slow))


@pytest.mark.parametrize("task", ["BaseReach-v0", "BasePickPlace-v0"])
def test_the_base_tasks_of_the_two_arms_are_one_task_space_in_the_base_frame(task):
    ur5e, panda = (load_task(f"{arm}{task}") for arm in ("UR5e", "Panda"))
    assert ur5e.frame == panda.frame == "base"
    same = ("observation", "action", "goal", "success", "objects", "episode_steps", "control_dt")
    for key in same:
        assert getattr(ur5e, key) == getattr(panda, key), key
