"""Registers the tsrl environments with Gymnasium (on `import tsrl`)."""

from __future__ import annotations

import gymnasium as gym

#: Registered environment ids.
ENV_IDS: tuple[str, ...] = ("tsrl/UR5eReach-v0", "tsrl/UR5ePickPlace-v0")
_ENTRY_POINTS = {
    "tsrl/UR5eReach-v0": "tsrl.envs.reach:UR5eReachEnv",
    "tsrl/UR5ePickPlace-v0": "tsrl.envs.pick_place:UR5ePickPlaceEnv",
}
#: Episode length in control steps (2 s at 25 Hz).
MAX_EPISODE_STEPS = 50


def register_envs() -> None:
    """Registers every id in ENV_IDS once; a second call is a no-op."""
    for env_id in ENV_IDS:
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=_ENTRY_POINTS[env_id], max_episode_steps=MAX_EPISODE_STEPS)
