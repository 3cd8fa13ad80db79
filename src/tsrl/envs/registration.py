"""Registers the tsrl environments with Gymnasium (on `import tsrl`): one id per built-in task, and
`tsrl/Task-v0`, which builds the task given as `task=` (a TOML file path or a Task)."""

from __future__ import annotations

import gymnasium as gym

from .tasks import BUILTIN_TASKS, load_task

#: Registered ids of the built-in tasks.
ENV_IDS: tuple[str, ...] = tuple(f"tsrl/{name}" for name in BUILTIN_TASKS)
#: The id that builds any task: gym.make(TASK_ENV_ID, task="my_task.toml", max_episode_steps=...).
TASK_ENV_ID = "tsrl/Task-v0"
ENTRY_POINT = "tsrl.envs.base:TaskEnv"


def register_envs() -> None:
    """Registers every built-in task (its episode length from its file) and TASK_ENV_ID; idempotent."""
    for name in BUILTIN_TASKS:
        env_id = f"tsrl/{name}"
        if env_id not in gym.registry:
            steps = load_task(name).episode_steps
            gym.register(id=env_id, entry_point=ENTRY_POINT, kwargs={"task": name}, max_episode_steps=steps)
    if TASK_ENV_ID not in gym.registry:
        gym.register(id=TASK_ENV_ID, entry_point=ENTRY_POINT)
