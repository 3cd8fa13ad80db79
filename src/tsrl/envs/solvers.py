"""Scripted solvers of the built-in tasks: they show every sampled goal is feasible, and demonstrate.

Each solver acts on the public observation dict (and, where a task's observation may not carry
what it needs, on the environment's own state, as a scripted controller may), through the task's
action map: it asks for the target values it wants and scales them into [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np

from ..taskmaps.relabel import quaternion_to_rotation
from .base import TaskEnv


class PoseReachSolver:
    """UR5ePoseReach-v0: the TCP straight to the goal position while turning the cup about the axis of
    the rotation from its orientation to the goal's, at most `max_turn` rad per step."""

    def __init__(self, env: TaskEnv, max_turn: float = 0.2):
        parts = env.task.action_spec.parts
        self.steps = [p.step for p in parts]  # position, vectorZ, vectorX
        self.max_turn = max_turn

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Nothing to remember between episodes."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        p, q = obs["achieved_goal"][:3], obs["achieved_goal"][3:7]
        p_goal, q_goal = obs["desired_goal"][:3], obs["desired_goal"][3:7]
        R = quaternion_to_rotation(q)
        R_next = _turn(q, q_goal, self.max_turn) @ R
        a_pos = (p_goal - p) / self.steps[0]
        a_z = (R_next[:, 2] - R[:, 2]) / self.steps[1]
        a_x = (R_next[:, 0] - R[:, 0]) / self.steps[2]
        return np.clip(np.concatenate([a_pos, a_z, a_x]), -1.0, 1.0)


class ObstacleReachSolver:
    """UR5eObstacleReach-v0: around the obstacle's side through a via point `clearance` m beyond its
    surface (horizontally, perpendicular to the start-goal line), then to the goal."""

    def __init__(self, env: TaskEnv, clearance: float = 0.1):
        self.env = env
        self.clearance = clearance
        self.step = env.task.action_spec.parts[0].step
        o = env.task.obstacle
        self._mocap = int(env.model.body_mocapid[env.model.body(o.body).id])
        self._geom = env.model.geom(o.geom).id
        self.via: np.ndarray | None = None

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Plans the via point from the TCP's start, the goal and the obstacle."""
        env = self.env
        start, goal = obs["achieved_goal"][:3], obs["desired_goal"][:3]
        center = env.data.mocap_pos[self._mocap].copy()
        radius = env.model.geom_size[self._geom, 0]
        line = goal - start
        side = np.cross(line, [0.0, 0.0, 1.0])
        side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([1.0, 0.0, 0.0])
        low, high = env.task.action_spec.parts[0].low, env.task.action_spec.parts[0].high
        for sign in (1.0, -1.0):
            self.via = center + sign * (radius + self.clearance) * side
            if np.all(self.via >= low) and np.all(self.via <= high):
                break

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        p = obs["achieved_goal"][:3]
        if self.via is not None and np.linalg.norm(self.via - p) < 0.03:
            self.via = None
        target = obs["desired_goal"][:3] if self.via is None else self.via
        return np.clip((target - p) / self.step, -1.0, 1.0)


def _turn(q: np.ndarray, q_goal: np.ndarray, max_angle: float) -> np.ndarray:
    """Rotation matrix (3, 3) of at most `max_angle` rad towards q_goal from q, about the world axis of
    the rotation q_goal q^-1."""
    w0, v0 = q[0], -q[1:]
    w1, v1 = q_goal[0], q_goal[1:]
    w = w1 * w0 - v1 @ v0  # q_goal * conj(q), Hamilton product
    v = w1 * v0 + w0 * v1 + np.cross(v1, v0)
    if w < 0:
        w, v = -w, -v
    norm = np.linalg.norm(v)
    angle = 2 * math.atan2(norm, w)
    if norm < 1e-12:
        return np.eye(3)
    angle = min(angle, max_angle)
    half = angle / 2
    return quaternion_to_rotation(np.array([math.cos(half), *(math.sin(half) * v / norm)]))
