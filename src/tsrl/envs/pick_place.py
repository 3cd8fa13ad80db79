"""UR5ePickPlaceEnv: pick a 4 cm box up with the suction cup and place it at a goal position."""

from __future__ import annotations

import numpy as np

from ..assets.ur5e import BOX_BODY
from ..kinematics import name_to_id
from .base import TsrlGoalEnv

#: Centre and half-extent [m] of the table region where the box starts and goals lie (x, y).
TABLE_REGION_CENTER = np.array([-0.49, -0.13])
TABLE_REGION_HALF_EXTENT = 0.15
#: Box half size [m]; the box rests with its centre at this height on the table top (z = 0).
BOX_HALF_SIZE = 0.02
#: Highest goal above the resting height [m]; half the goals lie on the table.
MAX_GOAL_LIFT = 0.3
#: Minimum distance [m] between the box's start and the goal (so an episode is never solved at reset).
MIN_START_GOAL_DISTANCE = 0.1


class UR5ePickPlaceEnv(TsrlGoalEnv):
    """## Description
    A UR5e with a suction cup picks a 4 cm box (free joint, 0.1 kg) from a table and places it at a
    goal (site `target`): on the table or in the air above it.

    ## Action Space
    As UR5eReach-v0, plus one last dimension for the suction cup: on above 0, off otherwise.

    ## Observation Space
    As UR5eReach-v0: a preset or spec in `observation`; `achieved_goal` is the box position.

    ## Goal
    achieved_goal = position(box), desired_goal = position(target), metres, world frame.

    ## Reward
    1 if ||achieved_goal - desired_goal|| < 0.05 m else 0 (sparse).

    ## Randomizations
    Box position uniform on the table in a 0.3 m x 0.3 m square in front of the robot; goal (x, y) in
    the same square, z on the table (half of the episodes) or up to 0.3 m above it; at least 0.1 m
    from the box. The arm starts at home.

    ## Success Conditions
    `info["is_success"]`: box within 0.05 m of the goal.

    ## Episode End
    Truncation after 50 steps; no termination; a physics blow-up truncates with
    `info["physics_unstable"] = True`.

    ## Arguments
    `gym.make("tsrl/UR5ePickPlace-v0", obs="fs1", action="taskspace")`; as UR5eReach-v0.

    ## Version History
    v0: initial release.
    """

    scene = "pick_place"
    achieved_goal_spec = f"position({BOX_BODY})"
    has_suction = True

    def _randomize(self) -> None:
        rng = self.np_random
        box_xy = TABLE_REGION_CENTER + rng.uniform(-TABLE_REGION_HALF_EXTENT, TABLE_REGION_HALF_EXTENT, 2)
        box = np.array([*box_xy, BOX_HALF_SIZE])
        while True:
            goal_xy = TABLE_REGION_CENTER + rng.uniform(
                -TABLE_REGION_HALF_EXTENT, TABLE_REGION_HALF_EXTENT, 2
            )
            lift = rng.uniform(0.0, MAX_GOAL_LIFT) if rng.uniform() < 0.5 else 0.0
            goal = np.array([*goal_xy, BOX_HALF_SIZE + lift])
            if np.linalg.norm(goal - box) >= MIN_START_GOAL_DISTANCE:
                break
        joint = self.model.body_jntadr[name_to_id(self.model, "body", BOX_BODY)]
        adr = self.model.jnt_qposadr[joint]
        self.data.qpos[adr : adr + 7] = [*box, 1.0, 0.0, 0.0, 0.0]
        self.data.mocap_pos[self._target_mocap] = goal
