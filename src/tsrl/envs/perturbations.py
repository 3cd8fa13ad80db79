"""A task's `[randomize]` on one model: the world perturbed per episode, seeded by the env's generator.

Model parameters (object mass, size and friction; servo gains; added joint damping; the TCP's offset) are
drawn at each reset from their nominal values; observation noise and control jitter every step;
action latency and the goal markers' offset once per episode. Nothing is drawn, and nothing
changes, for what `[randomize]` leaves at its defaults.

HER stays exact: relabelling moves the markers, which no perturbation of the world depends on; the
noise is additive and is carried only by rows whose relabelling rule is a translation (a row reading a
marker's orientation carries none), so a relabelled observation equals the one the environment emits
with the markers moved and the same noise.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..kinematics import name_to_id
from ..robots import BoundRobot
from ..taskmaps import Position, PositionDiff, Stack, Velocity
from .goals import Goal
from .tasks import Task

_FREE = int(mujoco.mjtJoint.mjJNT_FREE)
_SIZE_AXIS = {  # the size entry that is a geom's half-height along z
    int(mujoco.mjtGeom.mjGEOM_BOX): 2,
    int(mujoco.mjtGeom.mjGEOM_SPHERE): 0,
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): 1,
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): 1,
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): 2,
}


class Perturber:
    """Applies a task's `randomize` to its model and steps (see the module docstring)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        task: Task,
        robot: BoundRobot,
        goal: Goal,
        obs_map: Stack,
        n_substeps: int,
    ):
        self.spec = r = task.randomize
        self.model = model
        self.goal = goal
        self.n_substeps = n_substeps
        bodies = [name_to_id(model, "body", o.body) for o in task.objects]
        self._bodies = np.array(bodies, dtype=int)
        self._mass = model.body_mass[self._bodies].copy()
        self._inertia = model.body_inertia[self._bodies].copy()
        self._geoms = [
            list(range(model.body_geomadr[b], model.body_geomadr[b] + model.body_geomnum[b])) for b in bodies
        ]
        all_geoms = np.array([g for gs in self._geoms for g in gs], dtype=int)
        self._all_geoms = all_geoms
        self._size = model.geom_size[all_geoms].copy()
        self._rbound = model.geom_rbound[all_geoms].copy()
        self._friction = model.geom_friction[all_geoms, 0].copy()
        self._qpos_z = [int(model.jnt_qposadr[model.body_jntadr[b]]) + 2 for b in bodies]
        for body, o in zip(bodies, task.objects):
            if model.body_jntadr[body] < 0 or int(model.jnt_type[model.body_jntadr[body]]) != _FREE:
                raise InvalidConfig(f"object {o.body!r} needs a free joint to be placed at reset")
        self._ctrl = np.arange(model.nu)[robot.ctrl]
        self._kp = model.actuator_gainprm[self._ctrl, 0].copy()
        self._bias = model.actuator_biasprm[self._ctrl, 1:3].copy()
        dofs = [int(model.jnt_dofadr[name_to_id(model, "joint", j)]) for j in robot.joints]
        self._dofs = np.array(dofs, dtype=int)
        self._damping = model.dof_damping[self._dofs].copy()
        self._tcp_site = -1
        if r.tcp_offset > 0:
            self._tcp_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, robot.robot.tcp)
            if self._tcp_site < 0:
                raise InvalidConfig(
                    f"randomize.tcp_offset needs the TCP {robot.robot.tcp!r} to be a site (it is a body)"
                )
            self._tcp_pos = model.site_pos[self._tcp_site].copy()
        self._noisy_rows = (
            _translating_rows(obs_map, goal) if r.observation_noise > 0 else np.zeros(0, dtype=int)
        )
        self.noise = np.zeros(obs_map.dim)
        self._latency: deque[np.ndarray] = deque()
        self.goal_offset = np.zeros(goal.dim)  # the markers' offset, in goal-vector columns
        self._jitter = round(r.control_jitter * n_substeps)

    # -- per episode ----------------------------------------------------------------------------------
    def episode(self, data: mujoco.MjData, rng: np.random.Generator, action_dim: int) -> None:
        """Draws this episode's model parameters, latency and goal offset (objects and markers placed)."""
        r, m = self.spec, self.model
        if r.object_mass != (1.0, 1.0) and self._bodies.size:
            scale = rng.uniform(*r.object_mass, self._bodies.size)
            m.body_mass[self._bodies] = self._mass * scale
            m.body_inertia[self._bodies] = self._inertia * scale[:, None]
        if r.object_size != (1.0, 1.0) and self._bodies.size:
            col = 0
            for geoms, qz in zip(self._geoms, self._qpos_z):
                size = rng.uniform(*r.object_size)
                rows = slice(col, col + len(geoms))
                m.geom_size[geoms] = self._size[rows] * size
                m.geom_rbound[geoms] = self._rbound[rows] * size
                heights = [
                    self._size[col + i, _SIZE_AXIS.get(int(m.geom_type[g]), 2)] for i, g in enumerate(geoms)
                ]
                data.qpos[qz] += (size - 1.0) * max(heights, default=0.0)
                col += len(geoms)
        if r.object_friction != (1.0, 1.0) and self._all_geoms.size:
            col = 0
            for geoms in self._geoms:
                m.geom_friction[geoms, 0] = self._friction[col : col + len(geoms)] * rng.uniform(
                    *r.object_friction
                )
                col += len(geoms)
        if r.servo_gain != (1.0, 1.0):
            gain = rng.uniform(*r.servo_gain, self._ctrl.size)
            m.actuator_gainprm[self._ctrl, 0] = self._kp * gain
            m.actuator_biasprm[self._ctrl, 1:3] = self._bias * gain[:, None]
        if r.joint_damping != (0.0, 0.0):
            m.dof_damping[self._dofs] = self._damping + rng.uniform(*r.joint_damping, self._dofs.size)
        if self._tcp_site >= 0:
            m.site_pos[self._tcp_site] = self._tcp_pos + rng.uniform(-r.tcp_offset, r.tcp_offset, 3)
        low, high = r.latency_range
        if high > 0:
            k = int(rng.integers(low, high + 1))
            self._latency = deque(np.zeros(action_dim) for _ in range(k))
        if r.goal_offset > 0:
            offset = rng.uniform(-r.goal_offset, r.goal_offset, 3)
            self.goal_offset[:] = 0.0
            for i, part in enumerate(self.goal.parts):
                self.goal_offset[part.position] = offset
                data.mocap_pos[self.goal.marker_mocap(i)] += offset

    # -- per step ---------------------------------------------------------------------------------------
    def draw_noise(self, rng: np.random.Generator) -> None:
        """This step's observation noise (kept until the next draw, so `move_target` re-adds it)."""
        if self._noisy_rows.size:
            self.noise[self._noisy_rows] = rng.normal(0.0, self.spec.observation_noise, self._noisy_rows.size)

    def delayed(self, action: np.ndarray) -> np.ndarray:
        """The action to apply now: `action` itself, or the one from k control periods ago."""
        if not self._latency:
            return action
        self._latency.append(action.copy())
        return self._latency.popleft()

    def substeps(self, rng: np.random.Generator) -> int:
        """This step's physics substeps: the control period's, varied by the jitter."""
        if self._jitter == 0:
            return self.n_substeps
        return max(1, self.n_substeps + int(rng.integers(-self._jitter, self._jitter + 1)))

    def true_info(self, achieved: np.ndarray, desired: np.ndarray) -> dict[str, Any]:
        """Success and distance against the true goal (the markers less this episode's offset)."""
        _, info = self.goal.outcome(achieved, desired - self.goal_offset)
        return {"true_success": info["is_success"], "true_distance": info["distance"]}


def _translating_rows(obs_map: Stack, goal: Goal) -> np.ndarray:
    """Observation rows that may carry additive noise: every row except those of maps that read a
    marker whose relabelling is not a translation of their value (a marker of a pose part, read by
    anything but a position, a position difference or their velocities)."""
    rotating = {p.marker for p in goal.parts if p.quaternion is not None}
    rows: list[int] = []
    for part, span in zip(obs_map.parts, obs_map.slices.values()):
        inner = part.map if isinstance(part, Velocity) else part
        if rotating & set(part.frames) and not isinstance(inner, Position | PositionDiff):
            continue
        rows.extend(range(span.start, span.stop))
    return np.array(rows, dtype=int)
