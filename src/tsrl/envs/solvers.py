"""Scripted solvers of the built-in tasks: they show every sampled goal is feasible, and demonstrate.

One protocol (`Controller`: `reset(obs)` at the start of an episode, `act(obs)` each step) and one
registry (`SOLVERS`: each built-in task name -> its solver's class, built on the TaskEnv it acts in).
`tsrl demos record` (tsrl.agents.demonstrators), `benchmarks/solvers.py` and the tests use both.

Each solver acts on the public observation dict, or on the task maps evaluated on the environment's
own state where the task's observation may not carry what it needs (as a scripted controller may),
through the task's action map: it asks for the target values it wants and scales them into [-1, 1].
"""

from __future__ import annotations

import abc
import math
from typing import ClassVar, Protocol

import numpy as np

from ..exceptions import InvalidConfig
from ..taskmaps import parse_spec
from ..taskmaps.relabel import quaternion_to_rotation
from .actions import action_mode
from .base import TaskEnv
from .tasks import load_task


class Controller(Protocol):
    """Chooses an episode's actions from its observations (a scripted solver or a trained policy)."""

    name: str
    """Recorded with the demonstrations it makes, e.g. "scripted-pick-place"."""

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Called with the first observation of an episode (after the env's reset)."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The action (k,) in [-1, 1] for the observation."""


class Solver(abc.ABC):
    """A scripted solver of a built-in task: a Controller built on the TaskEnv it acts in."""

    name: str
    actions: ClassVar[tuple[str, ...]] = ()
    """The action modes it acts in (empty: only its task's own)."""

    def __init__(self, env: TaskEnv):
        self.env = env

    @abc.abstractmethod
    def reset(self, obs: dict[str, np.ndarray]) -> None:
        """Called with the first observation of an episode (after the env's reset)."""

    @abc.abstractmethod
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The action (k,) in [-1, 1] for the observation."""


class _TcpController(Solver):
    """Base of the reach and pick-place solvers: it moves the TCP by the task's first action part (a
    relative position step) towards a point `control` chooses from the positions of `spec`, evaluated
    on the environment's state, and holds every other part (taskspace_orient's scalar products) at its
    value at the episode's start; a suction dimension comes last."""

    spec: ClassVar[str]
    actions = ("taskspace", "taskspace_orient")

    def __init__(self, env: TaskEnv):
        if env.action_mode not in self.actions:
            raise InvalidConfig(
                f"the {self.name} solver acts in action modes {', '.join(self.actions)}; got {env.action_mode!r}"
            )
        super().__init__(env)
        parts = env.task.action_spec.parts
        assert parts[0].step is not None  # these modes' TCP position part is relative
        self.max_step = float(parts[0].step)
        self.positions = parse_spec(self.spec, env.model)
        # The parts after the TCP position are held at their start values: (y - center) / half_range.
        self.held = parts[1:]
        self.held_maps = parse_spec(", ".join(p.map for p in self.held), env.model) if self.held else None
        self.hold = np.zeros(0)

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        if self.held_maps is None:
            return
        y = self.held_maps(self.env.model, self.env.data).y
        slices = self.held_maps.slices
        held = [(y[slices[p.map]] - np.asarray(p.center)) / np.asarray(p.half_range) for p in self.held]
        self.hold = np.concatenate([np.zeros(0), *held])

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        y = self.positions(self.env.model, self.env.data).y
        action = self.control({name: y[s] for name, s in self.positions.slices.items()})
        action = np.concatenate([action[:3], self.hold, action[3:]])  # position, held parts, suction
        return action.astype(np.float32)

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        """The position action (3,) and, with suction, the suction command (1,), from named positions."""
        raise NotImplementedError


class ReachSolver(_TcpController):
    """Reach: a straight line to the goal at up to the full TCP step; the env's IK turns it into joints."""

    name = "scripted-reach"
    spec = "position(tcp), position(target)"

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        return np.clip((y["position(target)"] - y["position(tcp)"]) / self.max_step, -1.0, 1.0)


class PickPlaceSolver(_TcpController):
    """Pick-and-place: above the box, descend, suction on, lift, carry, release (goals on the table)
    or hold (in the air). Succeeds on >= 95 of 100 seeded episodes (tests/envs)."""

    name = "scripted-pick-place"
    spec = "position(tcp), position(box), position(target)"
    HOVER = 0.10  # m above the box top before descending
    #: m the cup target goes below the box top, to press the cup onto it. Deep enough that a descent
    #: a few mm short still meets the box: a clone of 4 mm demonstrations missed it by 2-5 mm
    #: (studies/learner-from-demos, the suction's failures).
    GRIP_DEPTH = 0.015
    CARRY_SPEED = 0.6  # fraction of the largest TCP step while the box hangs on the cup

    def __init__(self, env: TaskEnv):
        super().__init__(env)
        if not env.task.action_spec.suction:
            raise InvalidConfig(
                f"the {self.name} solver needs a suction dimension in {env.task.name}'s action"
            )
        self.box_half_size = float(env.model.geom("box").size[0])
        self.phase = "approach"

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        super().reset(obs)
        self.phase = "approach"

    def control(self, y: dict[str, np.ndarray]) -> np.ndarray:
        half = self.box_half_size
        tcp, box, goal = y["position(tcp)"], y["position(box)"], y["position(target)"]
        box_top = box + [0.0, 0.0, half]
        suction = -1.0
        if self.phase == "approach":
            target = box_top + [0.0, 0.0, self.HOVER]
            if np.linalg.norm(tcp - target) < 0.01:
                self.phase = "descend"
        if self.phase == "descend":
            target = box_top - [0.0, 0.0, self.GRIP_DEPTH]
            if tcp[2] < box_top[2] + 0.003:
                self.phase = "lift"
        if self.phase == "lift":
            suction = 1.0
            target = np.array([*box_top[:2], max(goal[2], half) + half + 0.08])
            if tcp[2] > target[2] - 0.02:
                self.phase = "carry"
        if self.phase == "carry":
            suction = 1.0
            target = goal + [0.0, 0.0, half]
            if goal[2] < 1.5 * half and np.linalg.norm(box - goal) < 0.01:
                self.phase = "release"
        if self.phase == "release":
            target = goal + [0.0, 0.0, half + 0.03]
        speed = self.CARRY_SPEED if self.phase in ("lift", "carry") else 1.0
        return np.append(np.clip((target - tcp) / self.max_step, -speed, speed), suction)


class PoseReachSolver(Solver):
    """UR5ePoseReach-v0: the TCP straight to the goal position while turning the cup about the axis of
    the rotation from its orientation to the goal's, at most `max_turn` rad per step."""

    name = "scripted-pose-reach"

    def __init__(self, env: TaskEnv, max_turn: float = 0.2):
        super().__init__(env)
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


class ObstacleReachSolver(Solver):
    """Obstacle reach: over the obstacle. The TCP rises to `clearance` m above the obstacle's top (or
    stays higher), crosses above the goal at that height, then descends onto the goal; the wrist is
    above the cup, so nothing passes the obstacle below its top."""

    name = "scripted-obstacle-reach"

    def __init__(self, env: TaskEnv, clearance: float = 0.08):
        super().__init__(env)
        self.clearance = clearance
        self.step = env.task.action_spec.parts[0].step
        o = env.task.obstacle
        assert o is not None  # the obstacle tasks have one
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


class PushSolver(Solver):
    """Push: the cup travels high to a point behind the box (on the far side from the goal), descends to
    the table and pushes the box along the box-goal line, slowing as it nears the goal; it backs off and
    approaches again when the box slips off the cup's line, and backs off and waits once the box is there.
    Reads the TCP's position from the environment (the observation need not carry it)."""

    name = "scripted-push"

    def __init__(
        self,
        env: TaskEnv,
        height: float = 0.09,
        push_z: float = 0.02,
        behind: float = 0.055,
        speed: float = 0.025,
    ):
        super().__init__(env)
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


#: The scripted solver of each built-in task that has one (names of tsrl.envs.tasks.BUILTIN_TASKS; the
#: environment id is "tsrl/<name>").


class GripperPickPlaceSolver(Solver):
    """Gripper pick-and-place: open above the object (goal part `part`), descend around it (at most
    `descend` m per period), close, lift (at most `lift` m per period), carry it `above` m over its goal, align to within `align` m,
    lower it onto the goal (at most `descend` m per period); with `release`, open there and rise.

    Reads the TCP's position from the environment (the observation need not carry it). `on`: the goal
    part whose object this one is put on (aimed at that object as it lies, plus the goals' offset)."""

    name = "scripted-gripper-pick-place"

    def __init__(
        self,
        env: TaskEnv,
        part: int = 0,
        release: bool = False,
        on: int | None = None,
        grasp_height: float = 0.0,
        above: float = 0.03,
        align: float = 0.01,
        descend: float = 0.02,
        lift: float = 0.05,
        close_steps: int = 6,
    ):
        super().__init__(env)
        if not env.task.action_spec.gripper:
            raise InvalidConfig(
                f"the {self.name} solver needs a gripper dimension in {env.task.name}'s action"
            )
        step = env.task.action_spec.parts[0].step
        assert step is not None  # the gripper tasks' position part moves by steps
        self.step = float(step)
        self._tcp = env.model.site(env.robot.tcp).id
        self.cols = slice(3 * part, 3 * part + 3)
        self.below = slice(3 * on, 3 * on + 3) if on is not None else None
        self.release = release
        self.grasp = np.array([0.0, 0.0, grasp_height])  # the grasp point above the object's centre
        self.clearance, self.travel = 0.06, 0.08  # hover above the grasp point; the lowest carry height
        self.above, self.align, self.descend, self.lift = above, align, descend, lift
        self.close_steps = close_steps  # the fingers close at 0.1 m/s: 4 mm per period
        self.phase, self.count, self.descending = "above", 0, False

    @property
    def done(self) -> bool:
        """Whether it has released the object and risen (with `release`)."""
        return self.phase == "done"

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        self.phase, self.count, self.descending = "above", 0, False

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        tcp = self.env.data.site_xpos[self._tcp]
        obj, goal = obs["achieved_goal"][self.cols], obs["desired_goal"][self.cols]
        if self.below is not None:  # onto the object below as it lies, not onto its goal
            goal = obs["achieved_goal"][self.below] + (goal - obs["desired_goal"][self.below])
        width = 1.0
        target = tcp.copy()
        if self.phase == "above":
            target = obj + self.grasp + [0.0, 0.0, self.clearance]
            if np.linalg.norm((tcp - target)[:2]) < 0.01 and abs(tcp[2] - target[2]) < 0.02:
                self.phase = "down"
        if self.phase == "down":  # at most `descend` per period, correcting the hand's sideways drift
            target = obj + self.grasp
            if np.linalg.norm(tcp - target) < 0.008:
                self.phase, self.count = "close", 0
            target = np.array([*target[:2], max(target[2], tcp[2] - self.descend)])
        if self.phase == "close":
            target, width = obj + self.grasp, -1.0
            self.count += 1
            if self.count >= self.close_steps:
                self.phase = "carry"
        if self.phase == "carry":
            width = -1.0
            above = max(goal[2] + self.above, self.travel)  # the object's height while it travels
            grip = tcp - obj
            off = float(np.linalg.norm((goal - obj)[:2]))
            self.descending = off < (3 * self.align if self.descending else self.align)  # hysteresis
            if not self.descending:
                if obj[2] < above - 0.02 and off > 0.03:  # lift first
                    target = np.array([*tcp[:2], min(above + grip[2], tcp[2] + self.lift)])
                else:  # over the goal, above it
                    target = np.array([*goal[:2], above]) + grip
            else:  # down onto the goal
                target = goal + grip
                target[2] = max(target[2], tcp[2] - self.descend)
                if self.release and np.linalg.norm(goal - obj) < 0.006:
                    self.phase, self.count = "open", 0
        if self.phase == "open":  # open fully before moving
            target = tcp.copy()
            self.count += 1
            if self.count >= 5:
                self.phase = "rise"
        if self.phase == "rise":  # straight up, slowly while the fingers are beside the object
            target = np.array([*tcp[:2], tcp[2] + 0.01])
            if tcp[2] > obj[2] + 0.04:
                target = np.array([*tcp[:2], obj[2] + self.clearance])
            if tcp[2] > obj[2] + self.clearance - 0.01:
                self.phase = "done"
        if self.phase == "done":
            target = tcp.copy()
        return np.append(np.clip((target - tcp) / self.step, -1.0, 1.0), width).astype(np.float32)


class StackSolver(Solver):
    """Stacking: the first box to its goal and released; then the second onto the first as it lies."""

    name = "scripted-stack"

    def __init__(self, env: TaskEnv):
        super().__init__(env)
        self.first = GripperPickPlaceSolver(env, 0, release=True)
        self.second = GripperPickPlaceSolver(env, 1, release=True, on=0)

    def reset(self, obs: dict[str, np.ndarray]) -> None:
        self.first.reset(obs)
        self.second.reset(obs)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return (self.second if self.first.done else self.first).act(obs)


class PegInsertSolver(GripperPickPlaceSolver):
    """Peg insertion: the peg grasped 2 cm above its centre once the fingers have closed on it, lifted
    slowly, carried 6 cm above the hole, aligned to within 1 mm, lowered in at 1 cm per period."""

    name = "scripted-peg-insert"

    def __init__(self, env: TaskEnv):
        super().__init__(
            env, grasp_height=0.02, above=0.06, align=0.001, descend=0.01, lift=0.015, close_steps=10
        )
        self.travel = 0.1


SOLVERS: dict[str, type[Solver]] = {
    "UR5eReach-v0": ReachSolver,
    "UR5eBaseReach-v0": ReachSolver,
    "UR5ePickPlace-v0": PickPlaceSolver,
    "UR5eBasePickPlace-v0": PickPlaceSolver,
    "UR5ePoseReach-v0": PoseReachSolver,
    "UR5eObstacleReach-v0": ObstacleReachSolver,
    "UR5eObstacleReach-v1": ObstacleReachSolver,
    "UR5ePush-v0": PushSolver,
    "PandaReach-v0": ReachSolver,
    "PandaBaseReach-v0": ReachSolver,
    "PandaPickPlace-v0": PickPlaceSolver,
    "PandaBasePickPlace-v0": PickPlaceSolver,
    "PandaPoseReach-v0": PoseReachSolver,
    "PandaObstacleReach-v0": ObstacleReachSolver,
    "PandaObstacleReach-v1": ObstacleReachSolver,
    "PandaPush-v0": PushSolver,
    "PandaPickPlaceGripper-v0": GripperPickPlaceSolver,
    "PandaStack-v0": StackSolver,
    "PandaPegInsert-v0": PegInsertSolver,
    "UR5ePegInsert-v0": PegInsertSolver,
}


def solver_for(env_id: str, action: str | None = None) -> type[Solver]:
    """The solver of the task `env_id` acting in action mode `action` (None or "task": the task's own
    action): a built-in task's ("tsrl/<name>"), or the one a task file names (its `solver` key, a
    built-in task); InvalidConfig naming what is accepted if it has none or acts otherwise. Reads the
    task's file, builds no environment."""
    name = env_id.removeprefix("tsrl/")
    task = None
    if name == env_id and env_id.endswith(".toml"):
        task = load_task(env_id)
        name = task.solver
    if name not in SOLVERS:
        named = "" if task is None else f" (a task file needs solver = a built-in task, {env_id} has none)"
        raise InvalidConfig(
            f"no scripted solver for {env_id!r}{named}; solved: {', '.join(f'tsrl/{n}' for n in SOLVERS)}"
        )
    solver = SOLVERS[name]
    own = action_mode((task or load_task(name)).action_spec)
    accepted = solver.actions or (own,)
    if (own if action in (None, "task") else action) not in accepted:
        which = "" if solver.actions else " (its task's own action)"
        raise InvalidConfig(
            f"the {solver.name} solver of {env_id} acts in action {' or '.join(accepted)}{which}; got {action!r}"
        )
    return solver
