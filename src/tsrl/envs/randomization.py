"""Start-state and goal randomisation of a task: objects, the goal marker's pose, an obstacle, start noise."""

from __future__ import annotations

import math
from typing import NamedTuple

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..ik import DlsSolver, IKOptions
from ..kinematics import name_to_id
from ..robots import BoundRobot
from ..taskmaps import parse_spec
from .goals import Goal, goal_positions
from .scenes import TARGET_BODY
from .tasks import FixtureSampler, ObjectSampler, ObstacleSampler, OrientationSampler, PositionSampler, Task

#: Penetration [m] of the goal's object into a fixture, at the goal, beyond which the task is refused.
FIXTURE_PENETRATION_TOLERANCE = 1e-4


def _check_fixture_clears_goal(
    model: mujoco.MjModel,
    task: Task,
    goal: Goal,
    fixture: FixtureSampler,
    mocap: int,
    object_qpos: dict[str, int],
    orientation: tuple[OrientationSampler, np.ndarray] | None,
) -> None:
    """Refuses a fixture that the goal's first object cannot stand in at its goal (a hole smaller
    than the peg): with the object at the goal box's centre in the goal's nominal orientation and the
    fixture at its offset from there, no contact between their geoms may be deeper than
    FIXTURE_PENETRATION_TOLERANCE. `object_qpos`: each object's free-joint qpos address."""
    frame = goal.parts[0].frame
    if frame not in object_qpos:
        return
    adr = object_qpos[frame]
    data = mujoco.MjData(model)
    center = np.array(task.goal.position.center, dtype=np.float64)
    quat = orientation[1] if orientation is not None else np.array([1.0, 0.0, 0.0, 0.0])
    data.qpos[adr : adr + 7] = [*center, *quat]
    data.mocap_pos[mocap] = center + np.array(fixture.offset)
    mujoco.mj_forward(model, data)
    body, fixture_body = name_to_id(model, "body", frame), name_to_id(model, "body", fixture.body)
    for c in data.contact[: data.ncon]:
        bodies = {int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])}
        if bodies == {body, fixture_body} and c.dist < -FIXTURE_PENETRATION_TOLERANCE:
            names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in (c.geom1, c.geom2)]
            raise InvalidConfig(
                f"{task.source or task.name}: [[fixtures]] body {fixture.body!r}: {frame!r} at its goal "
                f"penetrates it by {-c.dist * 1000:.1f} mm (geoms {names[0]!r} and {names[1]!r}: a hole "
                f"smaller than the object?); accepted: a fixture the object at its goal clears"
            )


class Randomizer:
    """Samples a task's start state and goal with the env's generator and writes them into MjData.

    Draw order (part of the seeded behaviour): start noise, objects, goal position (drawn again while
    too close to the first object or, with an obstacle, to the TCP's start), goal orientation,
    obstacle (with `clear_at_goal`: goal, orientation and obstacle again while no obstacle fits).
    """

    def __init__(self, model: mujoco.MjModel, task: Task, robot: BoundRobot, goal: Goal):
        self.model = model
        self.task = task
        self.goal = goal
        self._orientation: tuple[OrientationSampler, np.ndarray] | None = None  # the sampler, its nominal
        if task.goal.orientation is not None:
            sampler = task.goal.orientation
            nominal = np.array(sampler.nominal or model.body_quat[name_to_id(model, "body", TARGET_BODY)])
            self._orientation = (sampler, nominal)
        self._arm_qpos = robot.qpos
        self._arm_ctrl = robot.ctrl
        self._n_joints = len(robot.joints)
        self._objects = []
        for obj in task.objects:
            body = name_to_id(model, "body", obj.body)
            joint = model.body_jntadr[body]
            if joint < 0 or int(model.jnt_type[joint]) != int(mujoco.mjtJoint.mjJNT_FREE):
                raise InvalidConfig(f"object {obj.body!r} needs a free joint to be placed at reset")
            self._objects.append((int(model.jnt_qposadr[joint]), obj))
        self._fixtures: list[tuple[int, np.ndarray]] = []
        for fixture in task.fixtures:
            mocap = int(model.body_mocapid[name_to_id(model, "body", fixture.body)])
            if mocap < 0:
                raise InvalidConfig(f'fixture body {fixture.body!r} must be a mocap body (mocap="true")')
            self._fixtures.append((mocap, np.array(fixture.offset, dtype=np.float64)))
            objects = {obj.body: adr for adr, obj in self._objects}
            _check_fixture_clears_goal(model, task, goal, fixture, mocap, objects, self._orientation)
        self._obstacle: _Obstacle | None = None
        if task.obstacle is not None:
            o = task.obstacle
            mocap = int(model.body_mocapid[name_to_id(model, "body", o.body)])
            if mocap < 0:
                raise InvalidConfig(f"obstacle body {o.body!r} must be a mocap body")
            geom = name_to_id(model, "geom", o.geom)
            at_goal = _RobotAtGoal(model, task, robot) if o.clear_at_goal else None
            self._obstacle = _Obstacle(o, mocap, geom, name_to_id(model, "site", robot.robot.tcp), at_goal)

    def randomize(self, data: mujoco.MjData, rng: np.random.Generator) -> None:
        """Samples and sets the start state and goal in `data` (after a reset to the home keyframe)."""
        task = self.task
        if task.start_noise > 0:
            q = data.qpos[self._arm_qpos] + rng.uniform(-task.start_noise, task.start_noise, self._n_joints)
            data.qpos[self._arm_qpos] = q
            data.ctrl[self._arm_ctrl] = q
        starts: list[np.ndarray] = []
        for adr, obj in self._objects:
            pos = self._sample_object(rng, obj, starts)
            data.qpos[adr : adr + 7] = [*pos, 1.0, 0.0, 0.0, 0.0]
            starts.append(pos)
        obstacle = self._obstacle
        tcp_start = None
        if obstacle is not None:
            mujoco.mj_kinematics(self.model, data)
            tcp_start = data.site_xpos[obstacle.tcp_site].copy()
        for _ in range(_GOAL_AND_OBSTACLE_TRIES):
            goal = self._sample_goal(rng, starts, tcp_start)
            quat = (
                self._sample_orientation(rng, *self._orientation) if self._orientation is not None else None
            )
            for i, pos in enumerate(goal_positions(goal, task.goal.offsets)):
                self.goal.place_marker(data, i, pos, quat if i == 0 else None)
            for mocap, offset in self._fixtures:
                data.mocap_pos[mocap] = goal + offset
            if (
                obstacle is None
                or tcp_start is None
                or self._place_obstacle(data, rng, obstacle, tcp_start, goal)
            ):
                return
            if obstacle.at_goal is None:
                return  # v0 tasks keep the last draw of the obstacle
        assert obstacle is not None  # only the obstacle's rules can fail every draw
        raise InvalidConfig(
            f"{task.source or task.name}: obstacle: no goal and obstacle drawn in {_GOAL_AND_OBSTACLE_TRIES} "
            "tries leave the robot untouched at the start and at the goal with "
            f"{obstacle.spec.goal_clearance} m of room (goal_clearance); widen the goal box or lower "
            "goal_clearance or the obstacle's size"
        )

    def _sample_object(
        self, rng: np.random.Generator, obj: ObjectSampler, placed: list[np.ndarray]
    ) -> np.ndarray:
        """An object's start position (3,): drawn again while closer than its `min_separation` to an
        object placed before it (at most _GOAL_TRIES draws)."""
        for _ in range(_GOAL_TRIES):
            pos = _sample_box(rng, obj.center, obj.half_extent)
            if all(np.linalg.norm(pos - p) >= obj.min_separation for p in placed):
                return pos
        raise InvalidConfig(
            f"{self.task.source or self.task.name}: objects: min_separation = {obj.min_separation} m of "
            f"{obj.body!r}: no start in {_GOAL_TRIES} draws is that far from the objects placed before it; "
            "lower it or widen the objects' half_extent"
        )

    def _sample_goal(
        self, rng: np.random.Generator, objects: list[np.ndarray], tcp_start: np.ndarray | None
    ) -> np.ndarray:
        """The first goal part's position (3,): drawn again while too close to an object's start
        (`min_distance`) or, with an obstacle, to the TCP's start (at most _GOAL_TRIES draws)."""
        p: PositionSampler = self.task.goal.position
        rejected_by = ""
        for _ in range(_GOAL_TRIES):
            goal = _sample_box(rng, p.center, p.half_extent)
            if p.lift_probability > 0:
                lift = rng.uniform(0.0, p.max_lift) if rng.uniform() < p.lift_probability else 0.0
                goal[2] = goal[2] + lift
            if any(np.linalg.norm(goal - start) < p.min_distance for start in objects):
                rejected_by = f"goal.position.min_distance = {p.min_distance}"
                continue
            if (
                tcp_start is not None
                and self.task.obstacle is not None
                and np.linalg.norm(goal - tcp_start) < self.task.obstacle.min_goal_distance
            ):
                rejected_by = f"obstacle.min_goal_distance = {self.task.obstacle.min_goal_distance}"
                continue
            return goal
        raise InvalidConfig(
            f"{self.task.source or self.task.name}: {rejected_by} m: no goal in {_GOAL_TRIES} draws from the "
            "goal box is that far from the start; lower it or widen goal.position.half_extent"
        )

    @staticmethod
    def _sample_orientation(
        rng: np.random.Generator, o: OrientationSampler, nominal: np.ndarray
    ) -> np.ndarray:
        """The nominal orientation (4,) turned by a yaw about its z axis, then tilted within the cone."""
        cos_tilt = rng.uniform(math.cos(math.radians(o.cone)), 1.0)
        azimuth = rng.uniform(0.0, 2 * math.pi)
        yaw = rng.uniform(-math.radians(o.max_yaw), math.radians(o.max_yaw))
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, nominal)
        z = rot.reshape(3, 3)[:, 2]
        e1 = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        axis = math.cos(azimuth) * e1 + math.sin(azimuth) * np.cross(z, e1)
        tilt, turn, out, tmp = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
        mujoco.mju_axisAngle2Quat(tilt, axis, math.acos(min(cos_tilt, 1.0)))
        mujoco.mju_axisAngle2Quat(turn, np.array([0.0, 0.0, 1.0]), yaw)
        mujoco.mju_mulQuat(tmp, nominal, turn)
        mujoco.mju_mulQuat(out, tilt, tmp)
        return out

    def _place_obstacle(
        self,
        data: mujoco.MjData,
        rng: np.random.Generator,
        obstacle: _Obstacle,
        start: np.ndarray,
        goal: np.ndarray,
    ) -> bool:
        """Draws the obstacle until it touches nothing at the start, leaves `goal_clearance` m between its
        surface and the goal, horizontally, and, with `clear_at_goal`, touches nothing with the robot at
        the goal (at most `_OBSTACLE_TRIES` draws; the last one stays). Returns whether it meets them."""
        o, mocap, geom, _, at_goal = obstacle
        robot_at_goal = False  # solved once per goal, when a draw first needs it
        for _ in range(_OBSTACLE_TRIES):
            u = rng.uniform(o.fraction_low, o.fraction_high)
            center = start + u * (goal - start) + rng.uniform(-o.jitter, o.jitter, 3)
            radius, half_height = rng.uniform(*o.radius), rng.uniform(*o.half_height)
            self.model.geom_size[geom, :2] = (radius, half_height)
            self.model.geom_rbound[geom] = math.hypot(radius, half_height)
            data.mocap_pos[mocap] = center
            mujoco.mj_kinematics(self.model, data)
            mujoco.mj_collision(self.model, data)
            if _touches(data, geom) or np.linalg.norm((goal - center)[:2]) < radius + o.goal_clearance:
                continue
            if at_goal is None:
                return True
            if not robot_at_goal:
                at_goal.solve(data, goal)
                robot_at_goal = True
            if not at_goal.touches(data.mocap_pos, geom):
                return True
        return False


#: Draws of a goal position before its distance rules are given up as unmeetable.
_GOAL_TRIES = 1000
#: Draws of the obstacle before the last one is kept (each draw checks contacts and the goal's room).
_OBSTACLE_TRIES = 20
#: With `clear_at_goal`: draws of the goal (each with up to _OBSTACLE_TRIES obstacles) before giving up.
_GOAL_AND_OBSTACLE_TRIES = 100


class _Obstacle(NamedTuple):
    """The obstacle's sampler and ids: its mocap body, geom, the TCP site, and the robot at the goal
    (with `clear_at_goal`, else None)."""

    spec: ObstacleSampler
    mocap: int
    geom: int
    tcp_site: int
    at_goal: _RobotAtGoal | None


def _touches(data: mujoco.MjData, geom: int) -> bool:
    """Whether `geom` is in any contact of data's last mj_collision."""
    return any(geom in c.geom for c in data.contact[: data.ncon])


class _RobotAtGoal:
    """The robot at a position goal as the task's IK brings it there: a local solve (no restarts) from
    the start configuration to the goal with the action's held maps held (the cup down), in its own
    MjData; solved once per goal, then checked against each obstacle drawn for it."""

    def __init__(self, model: mujoco.MjModel, task: Task, robot: BoundRobot):
        if task.goal.map != f"position({robot.robot.tcp})":
            raise InvalidConfig(
                f"obstacle.clear_at_goal needs the goal map position({robot.robot.tcp}) (the IK solves the robot to "
                f"the goal); got {task.goal.map!r}"
            )
        spec = task.action_spec
        maps = ", ".join([task.goal.map, *(h.map for h in spec.hold)])
        self._held = np.concatenate([[], *(h.value for h in spec.hold)])
        options = IKOptions(restarts=0, posture=robot.posture)
        self._solver = DlsSolver(model, parse_spec(maps, model, robot.joints), robot.joints, options)
        self._data = mujoco.MjData(model)

    def solve(self, data: mujoco.MjData, goal: np.ndarray) -> None:
        """Solves the robot from data's state (its start) to `goal` (3,), in its own MjData."""
        at_goal = self._data
        at_goal.qpos[:], at_goal.mocap_quat[:] = data.qpos, data.mocap_quat
        self._solver.solve(at_goal, np.concatenate([goal, self._held]))

    def touches(self, mocap_pos: np.ndarray, geom: int) -> bool:
        """Whether `geom` touches anything with the robot as last solved and the mocap bodies at
        `mocap_pos` (n_mocap, 3)."""
        model, at_goal = self._solver.model, self._data
        at_goal.mocap_pos[:] = mocap_pos
        mujoco.mj_kinematics(model, at_goal)
        mujoco.mj_collision(model, at_goal)
        return _touches(at_goal, geom)


def _sample_box(rng: np.random.Generator, center, half_extent) -> np.ndarray:
    """center + uniform(-h, h) on the axes with h > 0 (the others are not drawn)."""
    pos = np.array(center, dtype=np.float64)
    h = np.asarray(half_extent, dtype=np.float64)
    axes = np.flatnonzero(h > 0)
    if axes.size:
        pos[axes] = pos[axes] + rng.uniform(-h[axes], h[axes], axes.size)
    return pos
