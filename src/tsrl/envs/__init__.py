"""Gymnasium goal environments built from tasks (TOML files): task-space observations, actions and goals."""

from .actions import ACTION_MODES, ACTION_PRESETS, ActionMap, ActionPart, ActionSpec, HeldPart
from .base import TaskEnv, checked_action
from .observations import OBS_PRESETS, parse_observation
from .registration import ENV_IDS, TASK_ENV_ID, register_envs
from .tasks import BUILTIN_TASKS, Task, load_task

__all__ = (
    "ACTION_MODES",
    "ACTION_PRESETS",
    "BUILTIN_TASKS",
    "ENV_IDS",
    "OBS_PRESETS",
    "TASK_ENV_ID",
    "ActionMap",
    "ActionPart",
    "ActionSpec",
    "HeldPart",
    "Task",
    "TaskEnv",
    "checked_action",
    "load_task",
    "parse_observation",
    "register_envs",
)
