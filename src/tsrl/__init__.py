"""tsrl: task-space reinforcement learning on MuJoCo (UR5e model, task maps, IK, goal environments)."""

import os

if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"  # off-screen by default on machines without a display

from .assets import SCENES, load_model
from .envs import ENV_IDS, OBS_PRESETS, register_envs
from .exceptions import ModelLoadError, TsrlError, UnknownName, UnknownScene
from .ik import DlsSolver, IKOptions, IKResult
from .kinematics import dh_forward, forward_kinematics
from .robots import ROBOTS, Robot, load_robot
from .taskmaps import TaskMap, TaskMapValue, parse_spec

register_envs()

__version__ = "0.1.0"

__all__ = (
    "ENV_IDS",
    "OBS_PRESETS",
    "ROBOTS",
    "SCENES",
    "DlsSolver",
    "IKOptions",
    "IKResult",
    "ModelLoadError",
    "Robot",
    "TaskMap",
    "TaskMapValue",
    "TsrlError",
    "UnknownName",
    "UnknownScene",
    "dh_forward",
    "forward_kinematics",
    "load_model",
    "load_robot",
    "parse_spec",
)
