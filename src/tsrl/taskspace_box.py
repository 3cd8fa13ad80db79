"""The box a robot's TCP position targets stay within: the bounds of the `taskspace` action presets.

A robot declares it (`Robot.reach_low`, `reach_high`; the built-in arms declare the built-in scenes'
table box), or it is `tsrl robot check`'s default reach box: +-DEFAULT_HALF_EXTENT around the TCP at
home in the robot's own model, prepared as a task prepares it (the box whose corners the check has
the IK reach).
"""

from __future__ import annotations

import functools
import warnings

import mujoco
import numpy as np

from .kinematics import arm_qpos_indices, name_to_id
from .robot_model import RobotNotice, load_robot_model
from .robots import HOME_KEY, Robot, reset_to_key
from .taskmaps import resolve_frame

#: Half-extent [m] of the default reach box around the TCP's home (Fetch's target range).
DEFAULT_HALF_EXTENT = 0.15


def home_key(model: mujoco.MjModel, robot: Robot) -> int | None:
    """The home keyframe's id in the robot's prepared model (joint values become HOME_KEY); None
    without `home` (the model's default pose)."""
    if robot.home is None:
        return None
    return name_to_id(model, "key", robot.home if isinstance(robot.home, str) else HOME_KEY)


def tcp_at_home(model: mujoco.MjModel, robot: Robot) -> np.ndarray:
    """The TCP's position (3,) [m, world] at home in the robot's prepared `model`."""
    data = mujoco.MjData(model)
    reset_to_key(model, data, home_key(model, robot))
    data.qpos[arm_qpos_indices(model, robot.joints)] = robot.home_q(model)
    mujoco.mj_kinematics(model, data)
    tcp = resolve_frame(model, robot.tcp)
    return (data.site_xpos[tcp.id] if tcp.kind == "site" else data.xpos[tcp.id]).copy()


@functools.cache
def taskspace_box(robot: Robot) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(low (3,), high (3,)) [m, world]: the robot's declared box, else the default reach box (module
    docstring; computed once per robot).

    Raises:
        TsrlError: the robot's model cannot be loaded (one line naming the robot file).
    """
    if robot.reach_low:
        return robot.reach_low, robot.reach_high
    with warnings.catch_warnings():  # the notices are the task's and the check's to give
        warnings.simplefilter("ignore", RobotNotice)
        model, _ = load_robot_model(robot, f"robot {robot.name!r}")
    center = tcp_at_home(model, robot)
    low = tuple(float(c) - DEFAULT_HALF_EXTENT for c in center)
    high = tuple(float(c) + DEFAULT_HALF_EXTENT for c in center)
    return low, high
