"""Tasks as data: the paper's MDP (observation, action, goal, reward) as a frozen dataclass loaded from TOML.

A task file (docs/tasks.md lists every key) names a robot and a scene, the observation spec, the
action (a built-in mode or task-map parts with their scaling and held maps), the goal (the
achieved-goal map and the sampler of the `target` mocap body's pose), the success tolerances and
reward, penalties, start-state randomisation, episode length and control period. `load_task`
validates everything it can without a model: unknown keys, wrong types, bad numbers; the
environment validates the rest (map and frame names, IK feasibility, relabelling) when it is built.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Literal

from ..configs import load_file
from ..exceptions import InvalidConfig, check_positive
from ..robots import ROBOTS, load_robot
from ..taskspace_box import taskspace_box
from .actions import ACTION_PRESETS, ActionPart, ActionSpec, HeldPart, preset


@dataclass(frozen=True)
class PositionSampler:
    """Goal positions: uniform in a box; optionally lifted; optionally away from the first object.

    Attributes:
        center: centre of the box [m], world frame.
        half_extent: half-extent [m] per axis; an axis with 0 is not sampled (stays at the centre).
        lift_probability: probability that a goal is lifted above the box by uniform(0, max_lift).
        max_lift: largest lift [m].
        min_distance: goals closer than this [m] to an object's start are drawn again.
    """

    center: tuple[float, float, float]
    half_extent: tuple[float, float, float]
    lift_probability: float = 0.0
    max_lift: float = 0.0
    min_distance: float = 0.0


@dataclass(frozen=True)
class OrientationSampler:
    """Goal orientations: the nominal orientation tilted within a cone, turned about its tool axis.

    The goal frame's z axis lies uniformly (by area) within `cone` degrees of the nominal z axis; its
    rotation about its own z axis is uniform within +-`max_yaw` degrees (180: any yaw).

    Attributes:
        nominal: the orientation (w, x, y, z) at zero tilt and yaw; default: the scene's target's.
        cone: largest tilt [deg] of the z axis from the nominal's.
        max_yaw: largest rotation [deg] about the z axis (180 = free yaw).
    """

    cone: float
    max_yaw: float = 180.0
    nominal: tuple[float, float, float, float] | None = None


@dataclass(frozen=True)
class GoalSpec:
    """The goal: what is achieved, and how the desired goal (the `target` mocap body) is sampled.

    Attributes:
        map: the achieved-goal map: "position(f)", a pose "position(f), quaternion(f)" of one
            frame f (the TCP, an object), or several frames "position(a), position(b)" (e.g. a
            stack; envs/goals.py); the desired goal is the same map of the markers `target`,
            `target_b`, ...
        position: sampler of the first part's target position.
        orientation: sampler of the target orientation (pose goals only).
        offsets: the later parts' target positions [m] relative to the first's, one per later
            part (e.g. [[0, 0, 0.04]]: the second box on top of the first).
    """

    map: str
    position: PositionSampler
    orientation: OrientationSampler | None = None
    offsets: tuple[tuple[float, float, float], ...] = ()


@dataclass(frozen=True)
class Penalty:
    """A reward term on a task map that does not read the goal (e.g. collisions).

    Added to the reward when the map's value exceeds `above`; the map's value is carried in the
    achieved goal (its desired value is 0), so the term stays exact when HER relabels the goal.

    Attributes:
        map: one task map spec, e.g. "accumulatedCollisions" or "distance(suction_cup, obstacle)".
        above: threshold: the penalty applies where the value is > above (below, with `below`).
        reward: added to the reward where it applies (e.g. -1).
        below: apply where the value is < above instead (e.g. a distance below a margin).
        terminate: end the episode (terminated=True) where it applies.
    """

    map: str
    above: float = 0.0
    reward: float = -1.0
    below: bool = False
    terminate: bool = False


@dataclass(frozen=True)
class SuccessSpec:
    """Paper eq. 8: success where every goal part is within its tolerance; the sparse reward.

    Attributes:
        position: tolerance [m] on the distance between achieved and desired positions.
        orientation: tolerance [deg] on the angle between achieved and desired orientations.
        reward: "0/1" (success 1, else 0; the paper) or "-1/0" (Gymnasium-Robotics' convention).
        penalties: reward terms on goal-independent task maps.
        reward_scale: the reward's success value needs every part within this fraction of its
            tolerances, in (0, 1] (a learner's margin: with a sparse reward at the tolerance itself, a
            goal at 0.99 of it is worth as much as one reached exactly); success itself, and so
            evaluation, is judged at the tolerances. 1: the reward's success is success.
    """

    position: float = 0.05
    orientation: float = 15.0
    reward: Literal["0/1", "-1/0"] = "0/1"
    penalties: tuple[Penalty, ...] = ()
    reward_scale: float = 1.0


@dataclass(frozen=True)
class ObjectSampler:
    """A free body placed at reset uniformly in a box (upright, at rest).

    Attributes:
        body: the body's name (it must have a free joint).
        center: centre of the box [m]; half_extent: per axis, 0 = not sampled.
        min_separation: drawn again while closer than this [m] to an object placed before it.
    """

    body: str
    center: tuple[float, float, float]
    half_extent: tuple[float, float, float]
    min_separation: float = 0.0


@dataclass(frozen=True)
class FixtureSampler:
    """A mocap body that moves with the goal at reset: at the first goal part's position plus `offset`.

    Attributes:
        body: the mocap body (e.g. the fixture a peg goes into); offset: [m], world frame.
    """

    body: str
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class ObstacleSampler:
    """A mocap obstacle placed at reset between the TCP's start and the goal.

    Its centre is start + u (goal - start), u uniform in [fraction_low, fraction_high], plus a
    uniform offset of +-jitter [m] per axis; its geom's radius and half-height are uniform in
    their ranges; it is drawn again while it touches anything at the start or its axis passes
    within radius + `goal_clearance` [m] of the goal (horizontally), or, with `clear_at_goal`, while
    it touches the robot at the goal (as a local IK solve from the start brings it there, the
    action's held maps held), at most 20 times. Then, with `clear_at_goal`, the goal is drawn again
    with new obstacles until all hold (an error after 100 goals); without it (the v0 tasks) the last
    obstacle drawn stays even if it touches the robot or crowds the goal. Goals closer to the start
    than `min_goal_distance` are drawn again.

    Attributes:
        body: the mocap body; geom: its collision geom (a cylinder or box).
    """

    body: str
    geom: str
    fraction_low: float = 0.4
    fraction_high: float = 0.6
    jitter: float = 0.01
    radius: tuple[float, float] = (0.03, 0.05)
    half_height: tuple[float, float] = (0.04, 0.08)
    min_goal_distance: float = 0.15
    goal_clearance: float = 0.08
    clear_at_goal: bool = False


@dataclass(frozen=True)
class Randomize:
    """Perturbations of the world, drawn per episode from the env's seeded generator (docs/tasks.md).

    Scales are uniform in [low, high] (1 = nominal); magnitudes 0 = off. The defaults change nothing:
    a task without `[randomize]` is today's task bit for bit.

    Attributes:
        object_mass, object_size, object_friction: scales of each object's body mass and inertia, its
            geoms' sizes (the object is placed higher by the growth of its half-height) and sliding
            friction.
        servo_gain: scale of the arm servos' stiffness and damping gains (kp, kv).
        joint_damping: passive damping [N m s/rad, or N s/m] added to each arm joint, uniform in
            [low, high] (the built-in arms have none; their servos damp).
        tcp_offset: the TCP frame moved by uniform(-x, x) [m] per axis in its body (a calibration error).
        observation_noise: standard deviation of Gaussian noise added to every observation row, in
            the row's units (m, m/s, unitless axis components, ...), drawn every step; rows that read
            a goal marker's orientation carry none (HER replaces them exactly).
        action_latency: each episode's actions act k control periods late, k uniform in 0..this,
            or in low..high for a pair [low, high] ([1, 1]: exactly one period); the first k steps
            hold the arm (zero action).
        control_jitter: each step's physics substeps vary by uniform +-round(this x substeps).
        goal_offset: the goal markers the policy sees are moved by uniform(-x, x) [m] per axis per
            episode from the true goal (a perception error); info["true_distance"] and
            info["true_success"] measure against the true goal.
    """

    object_mass: tuple[float, float] = (1.0, 1.0)
    object_size: tuple[float, float] = (1.0, 1.0)
    object_friction: tuple[float, float] = (1.0, 1.0)
    servo_gain: tuple[float, float] = (1.0, 1.0)
    joint_damping: tuple[float, float] = (0.0, 0.0)
    tcp_offset: float = 0.0
    observation_noise: float = 0.0
    action_latency: int | tuple[int, int] = 0
    control_jitter: float = 0.0
    goal_offset: float = 0.0

    @property
    def active(self) -> bool:
        """Whether anything is perturbed."""
        return self != Randomize()

    @property
    def latency_range(self) -> tuple[int, int]:
        """(low, high) control periods of `action_latency`: an integer k is (0, k)."""
        r = self.action_latency
        return (0, r) if isinstance(r, int) else r


#: Upper bounds on the counts and sizes a task file sets: past them an evaluation would run for
#: days or an observation grow without end, so they are refused when the file loads.
MAX_EPISODE_STEPS = 10_000  # 400 s at 25 Hz
MAX_PREVIOUS_ACTIONS = 100  # observed actions (a history of 4 s at 25 Hz)
MAX_OBJECTS = 32  # [[objects]] and [[fixtures]] tables each
MAX_CONTROL_DT = 1.0  # s
MAX_POSITION_TOLERANCE = 10.0  # m, success.position
MAX_ORIENTATION_TOLERANCE = 180.0  # deg, success.orientation

#: Randomize's scale keys, and its magnitude keys with their largest accepted values.
RANDOMIZE_SCALES = ("object_mass", "object_size", "object_friction", "servo_gain")
RANDOMIZE_MAGNITUDES = {
    "tcp_offset": 0.05,
    "observation_noise": 0.1,
    "action_latency": None,  # at most the episode's length less one
    "control_jitter": 0.5,
    "goal_offset": 0.1,
}


@dataclass(frozen=True)
class Task:
    """A task: the paper's MDP as data (docs/tasks.md).

    Attributes:
        name: the task's name (gym ids of built-in tasks are "tsrl/<name>").
        robot: a built-in robot (tsrl.robots.ROBOTS) or the path of a robot TOML file (relative to
            the task file; tsrl.robots.load_robot).
        scene: a built-in scene (tsrl.assets.SCENES) or the path of an MJCF/URDF file (relative to
            the task file); a scene without a `target` body gets one added.
        observation: an observation preset or task-map spec.
        action: a built-in action mode (ACTION_PRESETS) or an ActionSpec.
        goal: the goal map and its sampler.
        success: tolerances, reward convention and penalties.
        objects: free bodies placed at reset.
        fixtures: mocap bodies placed with the goal at reset.
        obstacle: an obstacle placed between the start and the goal at reset.
        start_noise: uniform noise [rad] added to each arm joint of the home pose at reset (0: none).
        episode_steps: control steps per episode.
        control_dt: control period [s] (a multiple of the scene's physics timestep).
        frame: "world", or "base": the scene expressed in the robot's base frame, so that every
            position of the task and every map value is relative to the base (envs/task_frames.py).
        randomize: perturbations of the world per episode (none by default).
        solver: a built-in task whose scripted solver demonstrates this one (e.g. a copy of it with
            a [randomize] table); empty: the task's own, where it is built in.
        previous_actions: the observation ends with the policy's last n actions, newest first (zeros
            at reset), so that a policy acting through action latency sees the actions still in flight.
        description: one line shown in listings.
    """

    name: str
    goal: GoalSpec
    robot: str = "ur5e"
    scene: str = "reach"
    observation: str = "baseline"
    action: ActionSpec | str = "taskspace"
    success: SuccessSpec = field(default_factory=SuccessSpec)
    objects: tuple[ObjectSampler, ...] = ()
    fixtures: tuple[FixtureSampler, ...] = ()
    obstacle: ObstacleSampler | None = None
    start_noise: float = 0.0
    episode_steps: int = 50
    control_dt: float = 0.04
    frame: Literal["world", "base"] = "world"
    randomize: Randomize = field(default_factory=Randomize)
    solver: str = ""
    previous_actions: int = 0
    description: str = ""
    #: The file the task was loaded from (scene paths are relative to it); None for tasks in code.
    source: Path | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        _validate(self)

    @property
    def robot_path(self) -> str | Path:
        """`robot` as load_robot takes it: a built-in name, or a path resolved against the task file."""
        if self.robot in ROBOTS or self.source is None or Path(self.robot).is_absolute():
            return self.robot
        return self.source.parent / self.robot

    @property
    def action_spec(self) -> ActionSpec:
        """The action as an ActionSpec (a built-in mode resolved with the robot's TCP box)."""
        return self._preset(self.action) if isinstance(self.action, str) else self.action

    def _preset(self, name: str) -> ActionSpec:
        """The built-in mode `name` bounded to the robot's box (tsrl.taskspace_box)."""
        return preset(name, *taskspace_box(load_robot(self.robot_path)))

    def with_overrides(
        self,
        obs: str | None = None,
        action: str | None = None,
        success_radius: float | None = None,
        reward_scale: float | None = None,
    ) -> Task:
        """This task with another observation (a preset or spec), a built-in action mode (the task's
        suction or gripper dimension kept), position tolerance [m] or reward scale
        (SuccessSpec.reward_scale); itself when nothing is given."""
        overrides: dict[str, Any] = {}
        if obs is not None:
            overrides["observation"] = obs
        if action is not None:
            if action not in ACTION_PRESETS:
                raise InvalidConfig(f"unknown action mode {action!r}; accepted: {', '.join(ACTION_PRESETS)}")
            overrides["action"] = self._preset(action).with_tool_of(self.action_spec)
        if success_radius is not None:
            if isinstance(success_radius, bool) or not success_radius > 0:
                raise InvalidConfig(f"success_radius must be > 0 m; got {success_radius}")
            overrides["success"] = dataclasses.replace(self.success, position=success_radius)
        if reward_scale is not None:
            check_reward_scale("reward_scale", reward_scale)
            success = overrides.get("success", self.success)
            overrides["success"] = dataclasses.replace(success, reward_scale=reward_scale)
        return dataclasses.replace(self, **overrides) if overrides else self


#: Built-in tasks: name -> TOML file under tsrl/envs/task_files.
BUILTIN_TASKS: dict[str, str] = {
    "UR5eReach-v0": "reach.toml",
    "UR5eBaseReach-v0": "base_reach.toml",
    "UR5ePickPlace-v0": "pick_place.toml",
    "UR5eBasePickPlace-v0": "base_pick_place.toml",
    "UR5ePoseReach-v0": "pose_reach.toml",
    "UR5eObstacleReach-v0": "obstacle_reach.toml",
    "UR5eObstacleReach-v1": "obstacle_reach_v1.toml",
    "UR5ePush-v0": "push.toml",
    "PandaReach-v0": "panda_reach.toml",
    "PandaBaseReach-v0": "panda_base_reach.toml",
    "PandaPickPlace-v0": "panda_pick_place.toml",
    "PandaBasePickPlace-v0": "panda_base_pick_place.toml",
    "PandaPoseReach-v0": "panda_pose_reach.toml",
    "PandaObstacleReach-v0": "panda_obstacle_reach.toml",
    "PandaObstacleReach-v1": "panda_obstacle_reach_v1.toml",
    "PandaPush-v0": "panda_push.toml",
    "PandaPickPlaceGripper-v0": "panda_pick_place_gripper.toml",
    "PandaStack-v0": "panda_stack.toml",
    "PandaPegInsert-v0": "panda_peg_insert.toml",
    "UR5ePegInsert-v0": "ur5e_peg_insert.toml",
}


def builtin_task_path(name: str) -> Path:
    """The TOML file of a built-in task."""
    if name not in BUILTIN_TASKS:
        raise InvalidConfig(f"unknown built-in task {name!r}; accepted: {', '.join(BUILTIN_TASKS)}")
    return Path(str(resources.files(__package__).joinpath("task_files", BUILTIN_TASKS[name])))


def load_task(task: Task | str | Path) -> Task:
    """A Task from a built-in name, a TOML file path, or a Task (returned as is).

    Raises:
        InvalidConfig: the file is missing or not TOML, or a key is unknown, of the wrong type or
            out of range (one line naming the file, the key and what is accepted).
    """
    if isinstance(task, Task):
        return task
    path = builtin_task_path(task) if isinstance(task, str) and task in BUILTIN_TASKS else Path(task)
    if not path.is_file():
        raise InvalidConfig(
            f"no task file {str(path)!r}; give a TOML file or a built-in task: {', '.join(BUILTIN_TASKS)}"
        )
    return load_file(Task, path, extra={"source": path})


# -- validation without a model ----------------------------------------------------------------------
def _validate(task: Task) -> None:
    _at_most("episode_steps", task.episode_steps, MAX_EPISODE_STEPS, "control steps")
    _at_most("control_dt", task.control_dt, MAX_CONTROL_DT, "s")
    _at_most("success.position", task.success.position, MAX_POSITION_TOLERANCE, "m")
    _at_most("success.orientation", task.success.orientation, MAX_ORIENTATION_TOLERANCE, "deg")
    check_reward_scale("success.reward_scale", task.success.reward_scale)
    for key, tables in (("objects", task.objects), ("fixtures", task.fixtures)):
        if len(tables) > MAX_OBJECTS:
            raise InvalidConfig(f"{len(tables)} [[{key}]] tables; accepted: at most {MAX_OBJECTS}")
    _validate_randomize(task.randomize, task.episode_steps)
    for key in ("object_mass", "object_size", "object_friction"):
        if getattr(task.randomize, key) != (1.0, 1.0) and not task.objects:
            raise InvalidConfig(
                f"randomize.{key} = {list(getattr(task.randomize, key))} scales objects but the task has "
                "no [[objects]]; accepted without objects: [1, 1] (or leave the key out)"
            )
    for obj in task.objects:
        if not obj.min_separation >= 0:
            raise InvalidConfig(
                f"objects: min_separation = {obj.min_separation:g} m of {obj.body!r}; accepted: >= 0 m"
            )
    if task.robot not in ROBOTS and not task.robot.endswith(".toml"):
        raise InvalidConfig(f"robot = {task.robot!r}; accepted: {', '.join(ROBOTS)} or a robot .toml file")
    if isinstance(task.action, str) and task.action not in ACTION_PRESETS:
        raise InvalidConfig(
            f"action = {task.action!r}; accepted: {', '.join(ACTION_PRESETS)} or an [action] table"
        )
    if task.solver and task.solver not in BUILTIN_TASKS:
        raise InvalidConfig(
            f"solver = {task.solver!r}; accepted: the built-in task whose solver acts in this one: "
            f"{', '.join(BUILTIN_TASKS)}"
        )
    most = min(task.episode_steps - 1, MAX_PREVIOUS_ACTIONS)
    if isinstance(task.previous_actions, bool) or not 0 <= task.previous_actions <= most:
        raise InvalidConfig(
            f"previous_actions = {task.previous_actions!r}; accepted: an integer from 0 to {most} "
            f"(episode_steps - 1, at most {MAX_PREVIOUS_ACTIONS})"
        )
    if not 0 <= task.start_noise < math.pi:
        raise InvalidConfig(f"start_noise must be in [0, pi) rad; got {task.start_noise}")
    p = task.goal.position
    if any(h < 0 for h in p.half_extent) or not 0 <= p.lift_probability <= 1 or p.max_lift < 0:
        raise InvalidConfig(
            "goal.position: half_extent and max_lift must be >= 0 and lift_probability in [0, 1]; "
            f"got {p.half_extent}, {p.max_lift}, {p.lift_probability}"
        )
    if p.min_distance > 0 and not task.objects:
        raise InvalidConfig(
            "goal.position.min_distance needs an object ([[objects]]) to keep the distance from"
        )
    for part in task.action_spec.parts:  # a built-in mode's with the robot's box (tsrl.taskspace_box)
        if part.map.startswith("position(") and part.low and part.high:
            _goal_within(task, part.low, part.high)
    o = task.goal.orientation
    if o is not None:
        if not 0 <= o.cone <= 90 or not 0 <= o.max_yaw <= 180:
            raise InvalidConfig(
                f"goal.orientation: cone must be in [0, 90] deg and max_yaw in [0, 180]; got {o}"
            )
        if o.nominal is not None and not math.isclose(math.hypot(*o.nominal), 1.0, abs_tol=1e-6):
            raise InvalidConfig(f"goal.orientation.nominal must be a unit quaternion; got {list(o.nominal)}")
    s = task.obstacle
    if s is not None and not (0 < s.fraction_low <= s.fraction_high < 1 and 0 < s.radius[0] <= s.radius[1]):
        raise InvalidConfig(
            f"obstacle: need 0 < fraction_low <= fraction_high < 1 and 0 < radius[0] <= radius[1]; got {s}"
        )


def check_reward_scale(key: str, value: float) -> None:
    """Refuses a reward scale (SuccessSpec.reward_scale) outside (0, 1]."""
    _at_most(key, value, 1.0, "(a fraction of the success tolerances)")


def _at_most(key: str, value: float, most: float, unit: str) -> None:
    """Refuses `value` unless it is a number in (0, most] (its unit named in the error)."""
    check_positive(key, value)
    if value > most:
        raise InvalidConfig(f"{key} = {value}; accepted: > 0 and at most {most:,g} {unit}")


def _validate_randomize(r: Randomize, episode_steps: int) -> None:
    for key in RANDOMIZE_SCALES:
        low, high = getattr(r, key)
        if not 0 < low <= high:
            raise InvalidConfig(f"randomize.{key} = [{low:g}, {high:g}]; accepted: scales 0 < low <= high")
    low, high = r.joint_damping
    if not 0 <= low <= high:
        raise InvalidConfig(f"randomize.joint_damping = [{low:g}, {high:g}]; accepted: 0 <= low <= high")
    for key, most in RANDOMIZE_MAGNITUDES.items():
        most = episode_steps - 1 if most is None else most
        if key == "action_latency":
            low, high = r.latency_range
            if not 0 <= low <= high <= most:
                given = r.action_latency if isinstance(r.action_latency, int) else f"[{low}, {high}]"
                raise InvalidConfig(
                    f"randomize.action_latency = {given}; accepted: 0 to {most} control periods, "
                    f"or [low, high] with 0 <= low <= high <= {most}"
                )
            continue
        value = getattr(r, key)
        if not 0 <= value <= most:
            raise InvalidConfig(f"randomize.{key} = {value:g}; accepted: 0 to {most:g}")


def _goal_within(task: Task, low: tuple[float, ...], high: tuple[float, ...]) -> None:
    """Goal positions must lie within the bounds of the TCP position target (else they cannot be reached)."""
    if not task.goal.map.startswith("position(tcp)"):
        return
    p = task.goal.position
    lo = [c - h for c, h in zip(p.center, p.half_extent)]
    hi = [c + h + (p.max_lift if i == 2 else 0.0) for i, (c, h) in enumerate(zip(p.center, p.half_extent))]
    if any(a < b for a, b in zip(lo, low)) or any(a > b for a, b in zip(hi, high)):
        raise InvalidConfig(
            f"goal.position box [{_fmt(lo)}] .. [{_fmt(hi)}] leaves the workspace the TCP target may reach, "
            f"[{_fmt(low)}] .. [{_fmt(high)}]"
            + (
                " (the action mode's box: the robot's reach_low/reach_high, else `tsrl robot check`'s "
                "reach box around the TCP at home)"
                if isinstance(task.action, str)
                else ""
            )
        )


def _fmt(v: Any) -> str:
    return ", ".join(f"{x:g}" for x in v)


__all__ = (
    "BUILTIN_TASKS",
    "ActionPart",
    "FixtureSampler",
    "GoalSpec",
    "HeldPart",
    "ObjectSampler",
    "ObstacleSampler",
    "OrientationSampler",
    "Penalty",
    "PositionSampler",
    "Randomize",
    "SuccessSpec",
    "Task",
    "builtin_task_path",
    "load_task",
)
