"""The reach goal box is reachable with the cup pointing down.

Exactly everywhere but a sliver at its far, high corner ((-x, -y, +z) relative to home), which lies up to
6 mm beyond the UR5e's reach with the cup vertical; a goal there is still achieved (success radius 5 cm).
"""

import itertools

import mujoco
import numpy as np

from tsrl.assets.ur5e import HOME_Q
from tsrl.envs import load_task
from tsrl.ik import DlsSolver
from tsrl.kinematics import forward_kinematics
from tsrl.taskmaps import parse_spec

#: The reach task's goal box: centre (the TCP at home) and half-extent.
HOME_TCP = np.array(load_task("UR5eReach-v0").goal.position.center)
GOAL_HALF_EXTENT = np.array(load_task("UR5eReach-v0").goal.position.half_extent)


def test_home_tcp_constant_matches_forward_kinematics(ur5e):
    model, data = ur5e
    forward_kinematics(model, data, HOME_Q)
    np.testing.assert_allclose(parse_spec("position(tcp)", model)(model, data).y, HOME_TCP, atol=1e-4)


def reach_cup_down(model, data, goal):
    task = parse_spec("position(tcp), vectorZ(tcp)", model)
    forward_kinematics(model, data, HOME_Q)
    result = DlsSolver(model, task).solve(data, np.concatenate([goal, [0.0, 0.0, -1.0]]))
    mujoco.mj_kinematics(model, data)
    return result, data.site("tcp").xpos.copy()


def test_random_goals_in_the_box_are_reached_exactly(ur5e, rng):
    model, data = ur5e
    for goal in HOME_TCP + rng.uniform(-GOAL_HALF_EXTENT, GOAL_HALF_EXTENT, (200, 3)):
        result, tcp = reach_cup_down(model, data, goal)
        assert result.converged, f"goal {goal} unreachable (error {result.error_norm:.2e})"
        np.testing.assert_allclose(tcp, goal, atol=2e-4)


def test_every_corner_of_the_box_is_reached_within_a_centimetre(ur5e):
    model, data = ur5e
    for signs in itertools.product((-1, 1), repeat=3):
        goal = HOME_TCP + GOAL_HALF_EXTENT * np.array(signs)
        _, tcp = reach_cup_down(model, data, goal)
        assert np.linalg.norm(tcp - goal) < 0.01, f"corner {signs}: {np.linalg.norm(tcp - goal):.3f} m away"
