"""How far an arm can carry a frame: goal boxes no configuration reaches are refused when a task builds.

A frame moved only by the controlled joints stays within `arm_reach` of the first joint's anchor in
every configuration: hinges keep the distance between consecutive anchors (and from the last anchor to
the frame), and a slide changes it by at most its travel. So a goal box corner farther than that,
plus the success tolerance, is a goal no policy reaches, whatever the action's bounds (a 0.75 m arm
asked for a goal 2 m away otherwise trains at 0 % without a word).
"""

from __future__ import annotations

import itertools

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..kinematics import name_to_id
from .tasks import Task


def arm_reach(
    model: mujoco.MjModel, data: mujoco.MjData, joints: tuple[str, ...], body: int, point: np.ndarray
) -> tuple[np.ndarray, float] | None:
    """(anchor (3,), R [m]): the first controlled joint's anchor in `data` (kinematics done) and the
    largest distance from it that `point` (3,), world frame, fixed on `body`, may have in any
    configuration; None where a joint that is not controlled (a free joint) also moves the body, or
    no joint does."""
    controlled = {name_to_id(model, "joint", j) for j in joints}
    path: list[int] = []  # the joints from the body up to the world
    while body > 0:
        first = int(model.body_jntadr[body])
        path += range(first, first + int(model.body_jntnum[body]))
        body = int(model.body_parentid[body])
    if not path or any(j not in controlled for j in path):
        return None
    chain = path[::-1]  # base to tip
    points = [data.xanchor[j] for j in chain] + [point]
    reach = sum(float(np.linalg.norm(b - a)) for a, b in itertools.pairwise(points))
    for j in chain:
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE:
            low, high = model.jnt_range[j]
            reach += float(high - low) if model.jnt_limited[j] else float("inf")
    return data.xanchor[chain[0]].copy(), reach


def check_goal_reachable(task: Task, model: mujoco.MjModel, joints: tuple[str, ...], frame: str) -> None:
    """Raises InvalidConfig, one line, where a corner of the goal position box (lift included) lies
    farther from the arm than `frame` (the goal's first frame) can be carried (module docstring)."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, frame)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    if sid >= 0:
        body, pos = int(model.site_bodyid[sid]), data.site_xpos[sid]
    else:
        body = name_to_id(model, "body", frame)
        pos = data.xpos[body]
    found = arm_reach(model, data, joints, body, pos)
    if found is None:
        return
    anchor, reach = found
    p = task.goal.position
    low = np.subtract(p.center, p.half_extent)
    high = np.add(p.center, p.half_extent) + [0.0, 0.0, p.max_lift]
    corners = np.array(list(itertools.product(*zip(low, high, strict=True))))
    distances = np.linalg.norm(corners - anchor, axis=1)
    far = int(np.argmax(distances))
    if distances[far] > reach + task.success.position:
        corner = ", ".join(f"{c:g}" for c in corners[far])
        raise InvalidConfig(
            f"goal.position: the box's corner [{corner}] is {distances[far]:.2f} m from the arm's first "
            f"joint, but {frame!r} reaches at most {reach:.2f} m from it; accepted: a goal box within "
            "the arm's reach (move goal.position.center, or shrink half_extent / max_lift)"
        )
