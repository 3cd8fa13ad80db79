"""Task-map specs: "position(tcp), velocity(positionDiff(tcp, target))" -> Stack; the map registry.

Named presets (the paper's observation configurations) belong to the environments
(tsrl.envs.observations.OBS_PRESETS); `parse_spec` expands the names of any presets table it is given."""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import partial

import mujoco

from ..exceptions import SpecError, UnknownName, UnknownTaskMap
from ..kinematics import Joints, controlled_joints
from .base import TaskMap
from .collision import AccumulatedCollisions, Distance
from .grasp import Oppose
from .gripper import GripperWidth
from .joint import JointLimits, JointState
from .orientation import AXES, Quaternion, QuaternionDiff, ScalarProduct, Vector
from .position import Position, PositionDiff, PositionRel
from .stack import Stack
from .suction import Suction
from .velocity import Velocity


@dataclass(frozen=True)
class MapEntry:
    """How the parser builds one map: argument kinds ("frame", "geom", "actuator" or "map") and a builder."""

    args: tuple[str, ...]
    build: Callable[..., TaskMap]  # build(model, *args); a "map" argument arrives built
    #: Whether the map reads the controlled joints: then build(model, *args, joints=joints).
    joints: bool = False


def _velocity(model: mujoco.MjModel, task_map: TaskMap) -> TaskMap:
    return Velocity(task_map)


def _axis_map(cls: type[Vector | ScalarProduct], axes: str, model: mujoco.MjModel, *frames: str) -> TaskMap:
    return cls(model, axes, *frames)


#: Every map name the parser knows (RAI feature symbols) -> its arguments and builder.
TASK_MAPS: dict[str, MapEntry] = {
    "position": MapEntry(("frame",), Position),
    "positionDiff": MapEntry(("frame", "frame"), PositionDiff),
    "positionRel": MapEntry(("frame", "frame"), PositionRel),
    "quaternion": MapEntry(("frame",), Quaternion),
    "quaternionDiff": MapEntry(("frame", "frame"), QuaternionDiff),
    **{f"vector{a}": MapEntry(("frame",), partial(_axis_map, Vector, a)) for a in AXES},
    **{
        f"scalarProduct{a}{b}": MapEntry(("frame", "frame"), partial(_axis_map, ScalarProduct, a + b))
        for a in AXES
        for b in AXES
    },
    "distance": MapEntry(("geom", "geom"), Distance),
    "accumulatedCollisions": MapEntry((), AccumulatedCollisions),
    "suction": MapEntry(("actuator",), Suction),
    "oppose": MapEntry(("geom", "geom", "geom"), Oppose),
    "gripperWidth": MapEntry(("actuator",), GripperWidth),
    "jointState": MapEntry((), JointState, joints=True),
    "jointLimits": MapEntry((), JointLimits, joints=True),
    "velocity": MapEntry(("map",), _velocity),
}


def known_maps() -> tuple[str, ...]:
    """Names of every task map the parser knows (presets not included)."""
    return tuple(TASK_MAPS)


def parse_spec(
    spec: str, model: mujoco.MjModel, joints: Joints = None, presets: Mapping[str, str] | None = None
) -> Stack:
    """Builds the task maps of a spec, e.g. "position(tcp), quaternion(tcp), scalarProductZZ(world, tcp)".

    A spec is a comma-separated list of maps `name(arg, ...)` (no parentheses for maps without
    arguments) and names of `presets` (name -> spec, e.g. tsrl.envs.OBS_PRESETS), which expand in
    place. Arguments are frame names
    (sites, else bodies; `world` is the world body), geom names (`distance`, `oppose`), an actuator
    (`suction`: an adhesion actuator; `gripperWidth`: a gripper's servo) or a map (`velocity`).
    Always returns a Stack, even for one map, so `slices` names every part.

    `joints` are the controlled joints that `jointState` and `jointLimits` read: hinge or slide joint
    names in order, or None (the default) for every hinge and slide joint of the model, which in
    the UR5e scenes are the six arm joints (see `tsrl.kinematics.joint_ids`). Pass a robot's joints
    (`tsrl.robots.Robot.joints`) where the model has other hinge or slide joints.

    Raises:
        UnknownTaskMap: a name that is neither a map nor a preset (the message lists both).
        UnknownName: a frame or geom the model does not have (the message lists the model's).
        SpecError: a syntax error (with its position) or a wrong argument count (with the expected
            count).
    """
    if joints is not None:
        joints = controlled_joints(model, joints)  # checked here, once for every map that reads them
    return Stack(_Parser(spec, joints, presets or {}).parse(model, ()))


@dataclass(frozen=True)
class _Node:
    name: str
    args: tuple[_Node, ...] | None  # None: written without parentheses
    pos: int

    def text(self) -> str:
        if self.args is None:
            return self.name
        return f"{self.name}({', '.join(a.text() for a in self.args)})"


_TOKEN = re.compile(r"\s*(?:(?P<name>[^\s,()]+)|(?P<punct>[,()]))")


class _Parser:
    """Recursive descent over: spec := item ("," item)* ; item := NAME ["(" [item ("," item)*] ")"]."""

    def __init__(self, spec: str, joints: Joints, presets: Mapping[str, str]):
        self.spec = spec
        self.joints = joints
        self.presets = presets
        self.tokens: list[tuple[str, str, int]] = []  # (kind, text, position)
        pos = 0
        while pos < len(spec):
            m = _TOKEN.match(spec, pos)
            if m is None:  # only trailing whitespace is left
                break
            group = "name" if m.group("name") else "punct"
            kind = "name" if group == "name" else m.group("punct")
            self.tokens.append((kind, m.group(group), m.start(group)))
            pos = m.end()
        self.tokens.append(("end", "", len(spec)))
        self.i = 0

    def error(self, message: str, pos: int) -> SpecError:
        return SpecError(f"{message} at position {pos} of spec {self.spec!r}")

    def expect(self, kind: str) -> tuple[str, str, int]:
        tok = self.tokens[self.i]
        if tok[0] != kind:
            found = "the end" if tok[0] == "end" else repr(tok[1])
            wanted = {"name": "a name", "end": "the end"}.get(kind, repr(kind))
            raise self.error(f"expected {wanted}, found {found}", tok[2])
        self.i += 1
        return tok

    def items(self) -> list[_Node]:
        nodes = [self.item()]
        while self.tokens[self.i][0] == ",":
            self.i += 1
            nodes.append(self.item())
        return nodes

    def item(self) -> _Node:
        _, name, pos = self.expect("name")
        if self.tokens[self.i][0] != "(":
            return _Node(name, None, pos)
        self.i += 1
        args: list[_Node] = []
        if self.tokens[self.i][0] != ")":
            args = self.items()
        self.expect(")")
        return _Node(name, tuple(args), pos)

    def parse(self, model: mujoco.MjModel, presets: tuple[str, ...]) -> list[TaskMap]:
        if not self.spec.strip():
            raise self.error("empty spec; expected task maps or presets", 0)
        nodes = self.items()
        self.expect("end")
        maps: list[TaskMap] = []
        for node in nodes:
            maps.extend(self.build(node, model, presets))
        return maps

    def build(self, node: _Node, model: mujoco.MjModel, presets: tuple[str, ...]) -> list[TaskMap]:
        if node.name in self.presets:
            if node.args is not None:
                raise self.error(f"preset {node.name} takes no arguments", node.pos)
            if node.name in presets:
                raise self.error(f"preset {node.name} refers to itself", node.pos)
            return _Parser(self.presets[node.name], self.joints, self.presets).parse(
                model, (*presets, node.name)
            )
        entry = TASK_MAPS.get(node.name)
        if entry is None:
            raise UnknownTaskMap(node.name, [*TASK_MAPS, *self.presets])
        args = node.args or ()
        if len(args) != len(entry.args):
            kinds = ", ".join(entry.args) or "none"
            raise self.error(
                f"{node.name} expects {len(entry.args)} argument(s) ({kinds}), got {len(args)}", node.pos
            )
        values: list[object] = []
        for k, (kind, arg) in enumerate(zip(entry.args, args), start=1):
            if kind == "map":
                if arg.name in self.presets:
                    raise self.error(
                        f"argument {k} of {node.name} must be one task map, not a preset", arg.pos
                    )
                values.extend(self.build(arg, model, presets))
            elif arg.args is not None:
                raise self.error(
                    f"argument {k} of {node.name} must be a {kind} name, got {arg.text()}", arg.pos
                )
            else:
                values.append(arg.name)
        try:
            if entry.joints:
                return [entry.build(model, *values, joints=self.joints)]
            return [entry.build(model, *values)]
        except SpecError as err:
            raise self.error(str(err), node.pos) from None
        except UnknownName as err:  # name the spec the unknown frame or geom stands in
            message = str(err)
            head, sep, tail = message.partition("; ")
            err.args = (f"{head} in spec {self.spec!r}{sep}{tail}",)
            raise err from None
