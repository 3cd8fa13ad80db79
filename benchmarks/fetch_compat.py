"""Lets Gymnasium-Robotics 1.4.2 (our speed and learning yardstick) run on mujoco 4, for benchmarks only.

Gymnasium-Robotics compares `model.jnt_type[i]` (a numpy integer) with `mujoco.mjtJoint.mjJNT_*`; on
mujoco 4 those are enum objects that no longer compare equal to integers, so `FetchReach-v4.reset()`
fails an assertion in `gymnasium_robotics.utils.mujoco_utils`. The patch gives that one module a view of
`mujoco` whose joint-type constants are plain ints; nothing else changes. tsrl itself never needs it.
"""

from __future__ import annotations

import sys
import types

import gymnasium as gym
import mujoco


class _IntJointTypes:
    mjJNT_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
    mjJNT_BALL = int(mujoco.mjtJoint.mjJNT_BALL)
    mjJNT_SLIDE = int(mujoco.mjtJoint.mjJNT_SLIDE)
    mjJNT_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)


class _MujocoWithIntJointTypes(types.ModuleType):
    mjtJoint = _IntJointTypes

    def __getattr__(self, name: str):
        return getattr(mujoco, name)


def register_fetch_envs() -> None:
    """Registers the Gymnasium-Robotics environments, patched to run on mujoco 4."""
    try:
        import gymnasium_robotics
        from gymnasium_robotics.utils import mujoco_utils
    except ImportError:
        sys.exit('FetchReach needs gymnasium-robotics 1.4.2: pip install -e ".[bench]" (or make bench)')
    if int(mujoco.__version__.split(".")[0]) >= 4:
        mujoco_utils.mujoco = _MujocoWithIntJointTypes("mujoco")
    gym.register_envs(gymnasium_robotics)
