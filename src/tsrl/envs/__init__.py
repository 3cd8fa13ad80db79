"""Gymnasium goal environments: UR5e reach and pick-and-place with task-space observations and actions."""

from .actions import ACTION_MODES, ActionConfig
from .base import TsrlGoalEnv, checked_action
from .registration import ENV_IDS, register_envs

__all__ = ("ACTION_MODES", "ENV_IDS", "ActionConfig", "TsrlGoalEnv", "checked_action", "register_envs")
