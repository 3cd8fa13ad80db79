"""Shared fixtures: our UR5e scenes loaded from package data, a seeded random generator."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: off-screen rendering in tests

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model


@pytest.fixture(scope="session")
def reach_model() -> mujoco.MjModel:
    return load_model("reach")


@pytest.fixture
def ur5e(reach_model: mujoco.MjModel) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The reach scene with fresh data, reset to the `home` keyframe."""
    data = mujoco.MjData(reach_model)
    mujoco.mj_resetDataKeyframe(reach_model, data, 0)
    mujoco.mj_forward(reach_model, data)
    return reach_model, data


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
