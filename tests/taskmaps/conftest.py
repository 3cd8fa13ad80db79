"""Helpers for the task-map tests: an example spec per registered map, finite differences, a pose
with the suction cup pressed into the table."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.assets.ur5e import HOME_Q
from tsrl.kinematics import forward_kinematics
from tsrl.taskmaps import TASK_MAPS, TaskMap, parse_spec

#: Example arguments per argument kind: a site and a body on different links, two geoms that can
#: touch, the suction cup's adhesion actuator, and an inner map for `velocity`.
EXAMPLE_ARGS = {
    "frame": ("tcp", "upper_arm_link"),
    "geom": ("suction_cup", "table"),
    "actuator": ("suction",),
}

#: Maps whose example needs arguments of its own: oppose, three geoms with polytope cores (the UR5e's
#: two capsules and the table); gripperWidth, an actuator on a joint or fixed tendon (the elbow servo:
#: its length is the elbow angle). tests/taskmaps/test_grasp.py tests both on the gripper Panda too.
EXAMPLE_SPECS = {
    "oppose": "oppose(upper_arm_tube, forearm_tube, table)",
    "gripperWidth": "gripperWidth(elbow)",
}

#: Maps whose value is only smooth near a chosen pose (the suction cup pressed into the table).
CONTACT_MAPS = ("distance", "accumulatedCollisions")


def example_spec(name: str, inner: str = "positionRel(tcp, upper_arm_link)") -> str:
    """A spec for the registered map `name`, e.g. "positionDiff(tcp, upper_arm_link)"."""
    if name in EXAMPLE_SPECS:
        return EXAMPLE_SPECS[name]
    kinds = TASK_MAPS[name].args
    if not kinds:
        return name
    args = [inner if kind == "map" else EXAMPLE_ARGS[kind][i] for i, kind in enumerate(kinds)]
    return f"{name}({', '.join(args)})"


def set_qpos(model: mujoco.MjModel, data: mujoco.MjData, qpos: np.ndarray) -> None:
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def finite_difference_jacobian(
    task_map: TaskMap, model: mujoco.MjModel, data: mujoco.MjData, eps: float = 1e-6
) -> np.ndarray:
    """Central differences of y over the tangent space at data.qpos (perturbed with mj_integratePos)."""
    q0 = data.qpos.copy()
    J = np.zeros((task_map.dim, model.nv))
    for k in range(model.nv):
        dq = np.zeros(model.nv)
        dq[k] = 1.0
        q_plus, q_minus = q0.copy(), q0.copy()
        mujoco.mj_integratePos(model, q_plus, dq, eps)
        mujoco.mj_integratePos(model, q_minus, dq, -eps)
        set_qpos(model, data, q_plus)
        y_plus = task_map(model, data).y
        set_qpos(model, data, q_minus)
        y_minus = task_map(model, data).y
        J[:, k] = task_map.difference(y_plus, y_minus) / (2 * eps)
    set_qpos(model, data, q0)
    return J


def pressed_into_table(model: mujoco.MjModel, depth: float = 0.004, tilt: float = 0.1) -> np.ndarray:
    """Arm angles (6,) with the cup tip `depth` below the table top and the cup tilted by `tilt` rad.

    The tilt makes one rim point the deepest, so the penetration depth is smooth in q.
    """
    data = mujoco.MjData(model)
    features = parse_spec("position(tcp), scalarProductZZ(world, tcp), scalarProductXX(world, tcp)", model)
    goal = np.array([-0.45, -0.1, -depth, -np.cos(tilt), 0.9])
    q = HOME_Q.copy()
    for _ in range(50):  # damped least squares on our own maps
        forward_kinematics(model, data, q)
        y, J = features(model, data)
        q = q + J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(len(y)), goal - y)
    return q


@pytest.fixture(scope="session")
def pressed_q(reach_model: mujoco.MjModel) -> np.ndarray:
    return pressed_into_table(reach_model)
