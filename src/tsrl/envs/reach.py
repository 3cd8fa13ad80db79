"""UR5eReachEnv: move the suction-cup tip to a goal position."""

from __future__ import annotations

import numpy as np

from ..assets.ur5e import TCP_SITE
from .base import TsrlGoalEnv

#: TCP position at the home pose [m] (DH forward kinematics plus the 7 cm cup), the centre of the goal box.
HOME_TCP = np.array([-0.4919, -0.1333, 0.4179])
#: Half-extent [m] of the goal box on each axis (Fetch's target range).
GOAL_HALF_EXTENT = 0.15


class UR5eReachEnv(TsrlGoalEnv):
    """## Description
    A UR5e with a suction cup on a table moves the cup's tip (site `tcp`) to a goal (site `target`).
    The arm is driven through task-space actions solved by damped least-squares IK (default), or by
    joint-target steps. The paper's reach task ("Feature-Space Reinforcement Learning for Robotic
    Manipulation"), built on our own UR5e model.

    ## Action Space
    `Box(-1, 1, (k,), float32)`; see docs/envs.md. `taskspace` (k = 3): the TCP position target moves
    by up to 5 cm per step along each axis, the IK keeps the cup pointing down. `taskspace_orient`
    (k = 6): position step plus target scalar products x.x, y.y, z.z of world and TCP axes. `joint`
    (k = 6): joint targets move by up to 0.126 rad per step (180 deg/s).

    ## Observation Space
    Dict with `observation` (the task maps of the preset or spec, float64; see
    `observation_structure`), `achieved_goal` (TCP position, 3) and `desired_goal` (goal position, 3).

    ## Goal
    achieved_goal = position(tcp), desired_goal = position(target), metres, world frame.

    ## Reward
    1 if ||achieved_goal - desired_goal|| < 0.05 m else 0 (sparse; Gymnasium-Robotics uses 0/-1).

    ## Randomizations
    The goal is uniform in a box of half-extent 0.15 m centred on the TCP's home position. The arm
    starts at the home pose, at rest.

    ## Success Conditions
    `info["is_success"]`: distance below 0.05 m.

    ## Episode End
    Truncation after 50 steps (2 s at 25 Hz); no termination. A physics blow-up truncates the episode
    with `info["physics_unstable"] = True`.

    ## Arguments
    `gym.make("tsrl/UR5eReach-v0", obs="fs1", action="taskspace")`; also `success_radius`,
    `ik_iterations`, `render_mode` ("rgb_array" | "human"), `width`, `height`.

    ## Version History
    v0: initial release.
    """

    scene = "reach"
    achieved_goal_spec = f"position({TCP_SITE})"

    def _randomize(self) -> None:
        goal = HOME_TCP + self.np_random.uniform(-GOAL_HALF_EXTENT, GOAL_HALF_EXTENT, 3)
        self.data.mocap_pos[self._target_mocap] = goal
