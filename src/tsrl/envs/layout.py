"""What a policy trained on a task reads and writes: the task's layout, and the check that two tasks
share it (so that a policy of one runs on the other: another arm, another model, another scene).

Two tasks share a layout when their observation rows (task-map specs in order, with their sizes),
goal rows (goal parts and penalty maps) and action (its parts with their scaling and bounds, the held
maps, the suction dimension, or joint steps for as many joints) are the same, at the same control
period. Names are compared as written in the specs (`tcp` on every robot is the robot's TCP), so a
task-space policy moves between arms; a joint-space policy only between arms of as many joints.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..exceptions import InvalidConfig
from .base import TaskEnv


@dataclass(frozen=True)
class Layout:
    """A task's layout (see the module docstring); rows are (spec, size) in order."""

    observation: tuple[tuple[str, int], ...]
    goal: tuple[tuple[str, int], ...]
    action: tuple[tuple[str, str], ...]
    control_dt: float


def layout(env: TaskEnv) -> Layout:
    """The layout of a tsrl environment (its unwrapped TaskEnv)."""
    observation = tuple((spec, s.stop - s.start) for spec, s in env.observation_structure.items())
    goal = tuple((spec, s.stop - s.start) for spec, s in env.goal_structure.items())
    spec = env.task.action_spec
    action: list[tuple[str, str]] = []
    if not spec.uses_ik:
        action.append(("joint steps", f"{len(env.robot.joints)} joints, {spec.joint_step:g} rad per unit"))
    for part in spec.parts:
        scale = (
            f"step {part.step:g}"
            if part.step is not None
            else f"center {part.center} half_range {part.half_range}"
        )
        bounds = f", low {part.low} high {part.high}" if part.low or part.high else ""
        action.append((part.map, scale + bounds))
    for held in spec.hold:
        action.append((held.map, f"held at {held.value}"))
    if spec.suction:
        action.append(("suction", "on above 0"))
    if spec.gripper and env.bound_robot.gripper_ctrl is not None:
        low, high = env.model.actuator_ctrlrange[env.bound_robot.gripper_ctrl]
        if spec.gripper_open_close:
            action.append(("gripper", f"open ({high:g} m) above 0, closed ({low:g} m) at or below"))
        else:
            action.append(("gripper", f"opening width {low:g} to {high:g} m"))
    return Layout(observation, goal, tuple(action), env.task.control_dt)


def check_same_layout(trained: Layout, other: Layout, trained_name: str, other_name: str) -> None:
    """Raises InvalidConfig naming the first row or part where `other` differs from `trained`."""
    for what, a, b in (
        ("observation row", trained.observation, other.observation),
        ("goal row", trained.goal, other.goal),
        ("action part", trained.action, other.action),
    ):
        for i in range(max(len(a), len(b))):
            mine = _describe(a[i]) if i < len(a) else "nothing"
            theirs = _describe(b[i]) if i < len(b) else "nothing"
            if mine != theirs:
                raise InvalidConfig(
                    f"{other_name} does not match the layout of {trained_name}: {what} {i} is {theirs} there, "
                    f"{mine} in {trained_name}; a policy runs only on a task with the same observation, goal and "
                    "action layout"
                )
    if trained.control_dt != other.control_dt:
        raise InvalidConfig(
            f"{other_name} does not match the layout of {trained_name}: control_dt {other.control_dt} s there, "
            f"{trained.control_dt} s in {trained_name}"
        )


def _describe(row: tuple[str, object]) -> str:
    name, detail = row
    return f"{name} ({detail})" if isinstance(detail, str) else f"{name} ({detail} values)"
