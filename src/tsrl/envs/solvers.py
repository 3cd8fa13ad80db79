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
    """Obstacle reach: over the obstacle. The TCP rises to `clearance` m above the obstacle's top (or
    stays higher), crosses above the goal at that height, then descends onto the goal; the wrist is
    above the cup, so nothing passes the obstacle below its top."""

    def __init__(self, env: TaskEnv, clearance: float = 0.08):
        self.env = env
        self.clearance = clearance
        self.step = env.task.action_spec.parts[0].step
        o = env.task.obstacle
        self._mocap = int(env.model.body_mocapid[env.model.body(o.body).id])
        self._geom = env.model.geom(o.geom).id
        self.vias: list[np.ndarray] = []

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Plans the via points from the TCP's start, the goal and the obstacle."""
        start, goal = obs["achieved_goal"][:3], obs["desired_goal"][:3]
        top = self.env.data.mocap_pos[self._mocap, 2] + self.env.model.geom_size[self._geom, 1]
        height = min(max(start[2], top + self.clearance), self.env.task.action_spec.parts[0].high[2])
        self.vias = [np.array([*start[:2], height]), np.array([*goal[:2], height])]

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        p = obs["achieved_goal"][:3]
        while self.vias and np.linalg.norm(self.vias[0] - p) < 0.03:
            self.vias.pop(0)
        target = self.vias[0] if self.vias else obs["desired_goal"][:3]
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


class PushSolver:
    """Push: the cup travels high to a point behind the box (on the far side from the goal), descends to
    the table and pushes the box along the box-goal line, slowing as it nears the goal; it backs off and
    approaches again when the box slips off the cup's line, and backs off and waits once the box is there.
    Reads the TCP's position from the environment (the observation need not carry it)."""

    def __init__(
        self,
        env: TaskEnv,
        height: float = 0.09,
        push_z: float = 0.02,
        behind: float = 0.055,
        speed: float = 0.025,
    ):
        self.env = env
        self.step = env.task.action_spec.parts[0].step
        assert self.step is not None  # the push tasks' position part moves by steps
        self._tcp = env.model.site(env.robot.tcp).id
        self.height, self.push_z, self.behind, self.speed = height, push_z, behind, speed
        self.pushing = self.done = False

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Starts in the approach phase."""
        self.pushing = self.done = False

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        tcp = self.env.data.site_xpos[self._tcp]
        box, goal = obs["achieved_goal"], obs["desired_goal"]
        to_goal = (goal - box)[:2]
        dist = float(np.linalg.norm(to_goal))
        if dist < 0.015 or (self.done and dist < 0.03):  # there: back off from the box and stay
            self.pushing, self.done = False, True
            away = tcp[:2] - box[:2]
            side = box[:2] + away / max(float(np.linalg.norm(away)), 1e-9) * 0.07
            return self._towards(tcp, np.array([*side, self.push_z + 0.02]))
        self.done = False
        d = to_goal / dist
        rel = (tcp - box)[:2]
        along, across = rel @ d, rel @ np.array([-d[1], d[0]])
        if self.pushing and (abs(across) > 0.02 or along > -0.02 or tcp[2] > self.push_z + 0.02):
            self.pushing = False  # the box slipped off the cup's line
        start = box[:2] - d * self.behind
        if self.pushing:
            advance = min(self.speed, 0.4 * dist)
            return self._towards(tcp, np.array([*(start + d * (0.01 + advance)), self.push_z]))
        if np.linalg.norm(tcp[:2] - start) <= 0.015:  # above or at the start point: descend, then push
            self.pushing = bool(tcp[2] < self.push_z + 0.005)
            return self._towards(tcp, np.array([*start, self.push_z]))
        away = tcp[:2] - box[:2]
        gap = float(np.linalg.norm(away))
        if tcp[2] > self.height - 0.015:  # high: travel above the start point
            target = np.array([*start, self.height])
        elif gap < 0.06:  # low beside the box: back off from it first, then rise
            target = np.array([*(box[:2] + away / max(gap, 1e-9) * 0.08), tcp[2] + 0.01])
        else:
            target = np.array([*tcp[:2], self.height])
        return self._towards(tcp, target)

    def _towards(self, tcp: np.ndarray, target: np.ndarray) -> np.ndarray:
        assert self.step is not None
        return np.clip((target - tcp) / self.step, -1.0, 1.0)
