"""Helpers for the IK tests: reachable targets from forward kinematics, a map that records iterates."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.kinematics import forward_kinematics
from tsrl.taskmaps import FrameCache, TaskMap, TaskMapValue, parse_spec

POSE = "position(tcp), quaternion(tcp)"
#: The paper's action: TCP position and the alignment of the world and TCP axes.
ALIGNMENT = (
    "position(tcp), scalarProductXX(world, tcp), scalarProductYY(world, tcp), scalarProductZZ(world, tcp)"
)


def target_at(model: mujoco.MjModel, task_map: TaskMap, q: np.ndarray) -> np.ndarray:
    """task_map's value at arm configuration q (6,): reachable by construction."""
    data = mujoco.MjData(model)
    forward_kinematics(model, data, q)
    return task_map(model, data).y


def within_limits(model: mujoco.MjModel, q: np.ndarray) -> bool:
    lo, hi = model.jnt_range[:6].T
    return bool(np.all(q >= lo) and np.all(q <= hi))


class Recording(TaskMap):
    """A real task map that also records data.qpos at every evaluation (to inspect every iterate)."""

    def __init__(self, inner: TaskMap):
        self.inner, self.dim, self.spec = inner, inner.dim, inner.spec
        self.qpos: list[np.ndarray] = []

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> TaskMapValue:
        self.qpos.append(data.qpos.copy())
        return self.inner(model, data)

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        self.inner.evaluate(cache, y, J)

    def difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self.inner.difference(a, b)


@pytest.fixture(scope="session")
def pick_place_model() -> mujoco.MjModel:
    return load_model("pick_place")


@pytest.fixture
def pose_map(reach_model: mujoco.MjModel) -> TaskMap:
    return parse_spec(POSE, reach_model)
