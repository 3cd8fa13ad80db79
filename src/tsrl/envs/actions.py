"""Action maps: how an agent's action a in [-1, 1]^k becomes joint targets, through the IK or directly.

An `ActionSpec` is data (part of a task): the task maps whose target values the agent sets, each
with its scaling, the maps the IK holds at fixed values, and an optional suction dimension. No
parts means joint actions (the end-to-end baseline, no IK). `ActionMap` is its run-time form for
one model: the IK map (parts, then held maps), the target layout, and `ik_target(a, y)`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..ik import DlsSolver
from ..taskmaps import Stack, TaskMap, Velocity, parse_spec


@dataclass(frozen=True)
class ActionPart:
    """One task map whose target value the agent sets.

    Attributes:
        map: one task map spec, e.g. "position(tcp)".
        step: relative scaling: target = current value + step * a (map units per action unit,
            e.g. 0.05 m for a position).
        center, half_range: absolute scaling: target = center + half_range * a (one entry per row
            of the map). Give either `step` or both of these.
        low, high: bounds the target is clipped to (e.g. the workspace), or empty.
    """

    map: str
    step: float | None = None
    center: tuple[float, ...] = ()
    half_range: tuple[float, ...] = ()
    low: tuple[float, ...] = ()
    high: tuple[float, ...] = ()


@dataclass(frozen=True)
class HeldPart:
    """A task map the IK holds at a fixed value, e.g. vectorZ(tcp) = (0, 0, -1): the cup points down."""

    map: str
    value: tuple[float, ...]


@dataclass(frozen=True)
class ActionSpec:
    """The action of a task: IK parts and held maps, or joint steps (no parts), plus optional suction.

    Attributes:
        parts: maps the agent sets, in action order; empty for joint actions.
        hold: maps the IK holds at fixed values.
        joint_step: radians a joint target moves per step at |a| = 1 (joint actions); the default is
            180 deg/s over one 40 ms control period.
        suction: whether a last action dimension commands the suction cup (on above 0).
        gripper: whether a last action dimension sets the gripper's opening width: the gripper
            servo's target is low + (a + 1) / 2 (high - low), its control range [m].
        gripper_open_close: with `gripper`, the dimension opens or closes instead: the servo's
            target is high above 0 and low at or below it (as the suction cup switches), so a
            closing command is always the full grip.
    """

    parts: tuple[ActionPart, ...] = ()
    hold: tuple[HeldPart, ...] = ()
    joint_step: float = 0.04 * math.pi
    suction: bool = False
    gripper: bool = False
    gripper_open_close: bool = False

    def __post_init__(self) -> None:
        if self.suction and self.gripper:
            raise InvalidConfig(
                "action: suction and gripper are both true; accepted: one tool dimension at most"
            )
        if self.gripper_open_close and not self.gripper:
            raise InvalidConfig(
                "action: gripper_open_close = true without gripper = true; accepted: "
                "gripper_open_close only with a gripper dimension"
            )

    def with_tool_of(self, other: ActionSpec) -> ActionSpec:
        """This action with `other`'s tool dimension (suction or gripper, and how the gripper's acts)."""
        return dataclasses.replace(
            self, suction=other.suction, gripper=other.gripper, gripper_open_close=other.gripper_open_close
        )

    @property
    def uses_ik(self) -> bool:
        return bool(self.parts)


#: The TCP position part of the presets; its bounds are the robot's (`preset`).
_POSITION = ActionPart("position(tcp)", step=0.05)

#: Built-in action modes (a task's `action` may name one; the env's `action` argument overrides it),
#: without bounds: `preset(name, low, high)` bounds their TCP position to a robot's box.
ACTION_PRESETS: dict[str, ActionSpec] = {
    # The cup points down: TCP z axis = -world z (equivalently scalarProductZZ(world, tcp) = -1, but
    # the axis form has a full-rank Jacobian at the target, so the IK converges fast).
    "taskspace": ActionSpec(parts=(_POSITION,), hold=(HeldPart("vectorZ(tcp)", (0.0, 0.0, -1.0)),)),
    # The paper's action set: TCP position plus target values of the scalar products x.x, y.y, z.z.
    "taskspace_orient": ActionSpec(
        parts=(
            _POSITION,
            *(
                ActionPart(f"scalarProduct{a}{a}(world, tcp)", center=(0.0,), half_range=(1.0,))
                for a in "XYZ"
            ),
        )
    ),
    "joint": ActionSpec(),
}
#: What each built-in mode means (for help texts and errors).
ACTION_MODES: dict[str, str] = {
    "taskspace": "TCP position step (3), cup held pointing down by the IK",
    "taskspace_orient": "TCP position step (3) + target scalar products x.x, y.y, z.z of world and TCP axes (3)",
    "joint": "joint target steps (one per arm joint), no IK (the end-to-end baseline)",
}


def preset(name: str, low: tuple[float, ...], high: tuple[float, ...]) -> ActionSpec:
    """The built-in mode `name` with its TCP position target kept in the box [low, high] [m, world]
    (a robot's: tsrl.taskspace_box)."""
    return _bounded(ACTION_PRESETS[name], low, high)


def _bounded(spec: ActionSpec, low: tuple[float, ...], high: tuple[float, ...]) -> ActionSpec:
    """`spec` with the bounds of its position(tcp) parts replaced by [low, high]."""
    parts = tuple(
        dataclasses.replace(p, low=low, high=high) if p.map == _POSITION.map else p for p in spec.parts
    )
    return dataclasses.replace(spec, parts=parts)


def action_mode(spec: ActionSpec) -> str:
    """The built-in mode (ACTION_PRESETS) `spec` is, whatever its TCP box and with or without its tool
    dimension; else "task"."""
    unbounded = _bounded(spec, (), ())
    for name, mode in ACTION_PRESETS.items():
        if mode.with_tool_of(spec) == unbounded:
            return name
    return "task"


class _Part(NamedTuple):
    """An action part's layout: its action columns, IK-target rows and scaling."""

    cols: slice
    rows: slice
    step: float | None  # relative scaling, or None for absolute
    center: np.ndarray
    half_range: np.ndarray
    bounds: tuple[np.ndarray, np.ndarray] | None  # (low, high) the target is clipped to


class ActionMap:
    """An ActionSpec bound to a model: the IK map and how an action sets its target.

    `ik_map` stacks the parts, then the held maps (`held_map`, their values `held_target`);
    `ik_target(a, y)` writes the target of the IK map for action a given the IK map's current value
    y, into one buffer it returns each time. `dim` is the action's size (parts, or one per joint for
    joint actions, plus the suction or gripper dimension).
    """

    def __init__(self, spec: ActionSpec, model: mujoco.MjModel, n_joints: int):
        self.spec = spec
        self.ik_map: Stack | None = None
        self.held_map: Stack | None = None
        self.held_target = np.zeros(0)
        self.dim = n_joints + int(spec.suction) + int(spec.gripper)
        self._parts: list[_Part] = []
        if not spec.uses_ik:
            return
        maps = [_one_map(p.map, model) for p in spec.parts] + [_one_map(h.map, model) for h in spec.hold]
        specs = [m.spec for m in maps]
        repeated = sorted({s for s in specs if specs.count(s) > 1})
        if repeated:
            raise InvalidConfig(f"action map {repeated[0]} is given twice; each map may be set or held once")
        self.ik_map = Stack(maps)
        self.target = np.zeros(self.ik_map.dim)
        rows_of = list(self.ik_map.slices.values())
        col = 0
        for part, m, rows in zip(spec.parts, maps, rows_of):
            _check_part(part, m.dim)
            cols = slice(col, col + m.dim)
            col += m.dim
            bounds = None
            if part.low or part.high:
                bounds = (np.array(part.low or [-np.inf] * m.dim), np.array(part.high or [np.inf] * m.dim))
            self._parts.append(
                _Part(cols, rows, part.step, np.array(part.center), np.array(part.half_range), bounds)
            )
        held_maps = maps[len(spec.parts) :]
        for held, m, rows in zip(spec.hold, held_maps, rows_of[len(spec.parts) :]):
            if len(held.value) != m.dim or not all(math.isfinite(v) for v in held.value):
                raise InvalidConfig(
                    f"held value of {m.spec} must be {m.dim} finite numbers; got {list(held.value)}"
                )
            self.target[rows] = held.value
        if held_maps:
            self.held_map = Stack(held_maps)
            self.held_target = np.concatenate([h.value for h in spec.hold])
        self.dim = col + int(spec.suction) + int(spec.gripper)

    def ik_target(self, a: np.ndarray, y: np.ndarray) -> np.ndarray:
        """The IK map's target (dim,) for action a (k,) at the IK map's current value y (dim,)."""
        target = self.target
        for cols, rows, step, center, half_range, bounds in self._parts:
            t = target[rows]
            if step is not None:  # relative: y + step * a, within the bounds
                np.multiply(a[cols], step, out=t)
                np.add(y[rows], t, out=t)
            else:  # absolute: center + half_range * a
                np.multiply(a[cols], half_range, out=t)
                np.add(t, center, out=t)
            if bounds is not None:
                np.minimum(np.maximum(t, bounds[0], out=t), bounds[1], out=t)
        return target

    def joint_targets(self, q: np.ndarray, a: np.ndarray, joint_range: np.ndarray) -> np.ndarray:
        """Joint actions' servo targets (n,): q + joint_step a (n,) within the joints' range (n, 2)."""
        step = self.spec.joint_step
        return np.minimum(np.maximum(q + step * a[: len(q)], joint_range[:, 0]), joint_range[:, 1])

    def check_holds(self, model: mujoco.MjModel, data: mujoco.MjData, joints: tuple[str, ...]) -> None:
        """Raises InvalidConfig unless the IK meets the held values from the state in `data` (kinematics
        done; home): catches conflicting held maps (e.g. two axes) and unreachable values."""
        if self.held_map is None:
            return
        result = DlsSolver(model, self.held_map, joints).solve(data, self.held_target)
        if not result.converged:
            raise InvalidConfig(
                f"the IK cannot hold {self.held_map.spec} at {self.held_target.round(3).tolist()} "
                f"(residual {result.error_norm:.3g} from home): conflicting or unreachable held values"
            )


def _one_map(spec: str, model: mujoco.MjModel) -> TaskMap:
    stack = parse_spec(spec, model)
    if len(stack.parts) != 1 or isinstance(stack.parts[0], Velocity):
        raise InvalidConfig(f"an action part must be one position-level task map; got {spec!r}")
    return stack.parts[0]


def _check_part(part: ActionPart, dim: int) -> None:
    name = part.map
    if part.step is not None:
        if part.center or part.half_range:
            raise InvalidConfig(f"action part {name}: give either step or center and half_range, not both")
        if not (math.isfinite(part.step) and part.step > 0):
            raise InvalidConfig(f"action part {name}: step must be > 0; got {part.step}")
    elif len(part.center) != dim or len(part.half_range) != dim:
        raise InvalidConfig(
            f"action part {name}: give step, or center and half_range with {dim} entries each "
            f"(got {len(part.center)} and {len(part.half_range)})"
        )
    for key in ("low", "high"):
        bound = getattr(part, key)
        if bound and len(bound) != dim:
            raise InvalidConfig(f"action part {name}: {key} needs {dim} entries; got {len(bound)}")
