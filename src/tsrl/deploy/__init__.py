"""Deployment: export a run (`tsrl export`, tsrl.deploy.export, needs torch) and run it on a robot
behind the safety layer (Controller, backends, the deploy loop: numpy, mujoco and onnxruntime only).

`export_run` and `export_policy` load on first use, so importing tsrl.deploy never imports torch.
"""

from __future__ import annotations

import importlib
from typing import Any

from .backends import (
    BackendError,
    FrankaBackend,
    MujocoBackend,
    RobotBackend,
    RobotState,
    ShadowBackend,
    UrRtdeBackend,
    check_backend,
)
from .contract import ContractError, read_contract
from .controller import Controller, ControllerOptions, Cycle
from .loop import read_log, replay, run_episodes
from .safety import JointLimiter

_LAZY = {"export_run": "export", "export_policy": "export"}

__all__ = (
    "BackendError",
    "ContractError",
    "Controller",
    "ControllerOptions",
    "Cycle",
    "FrankaBackend",
    "JointLimiter",
    "MujocoBackend",
    "RobotBackend",
    "RobotState",
    "ShadowBackend",
    "UrRtdeBackend",
    "check_backend",
    "export_policy",
    "export_run",
    "read_contract",
    "read_log",
    "replay",
    "run_episodes",
)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
