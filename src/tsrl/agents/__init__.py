"""Agents: DDPG/TD3/SAC with feature-aware HER, built by a factory; training runs, checkpoints, evaluation.

The configs and run folders import fast; the rest (torch, stable-baselines3) loads on first use, so
`tsrl --help` and `tsrl show` stay quick.
"""

from __future__ import annotations

import importlib
from typing import Any

from .config import ALGOS, AgentConfig, DemoConfig, HerConfig, TrainConfig
from .run_folder import NotARunFolder, load_config, read_progress

_LAZY = {
    "make_agent": "factory",
    "make_env": "factory",
    "make_vec_env": "factory",
    "FeatureHerReplayBuffer": "her",
    "TrainingInterrupted": "training",
    "resume": "training",
    "train": "training",
    "evaluate_run": "evaluation",
    "render_run": "evaluation",
}

__all__ = (
    "ALGOS",
    "AgentConfig",
    "DemoConfig",
    "FeatureHerReplayBuffer",
    "HerConfig",
    "NotARunFolder",
    "TrainConfig",
    "TrainingInterrupted",
    "evaluate_run",
    "load_config",
    "make_agent",
    "make_env",
    "make_vec_env",
    "read_progress",
    "render_run",
    "resume",
    "train",
)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
