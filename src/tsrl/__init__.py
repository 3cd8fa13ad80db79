"""tsrl: task-space reinforcement learning on MuJoCo (UR5e model, task maps, IK, goal environments)."""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"  # off-screen by default on machines without a display

from .assets import SCENES, load_model
from .exceptions import ModelLoadError, TsrlError, UnknownName, UnknownScene
from .kinematics import dh_forward, forward_kinematics
from .taskmaps import OBS_PRESETS, TaskMap, TaskMapValue, parse_spec

__version__ = "0.1.0"

__all__ = (
    "OBS_PRESETS",
    "SCENES",
    "ModelLoadError",
    "TaskMap",
    "TaskMapValue",
    "TsrlError",
    "UnknownName",
    "UnknownScene",
    "dh_forward",
    "forward_kinematics",
    "load_model",
    "parse_spec",
)
