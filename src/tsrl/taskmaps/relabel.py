"""Relabelling rules: a task map's value after a goal frame moved, computed from its old value alone.

HER gives a stored transition a new goal; the goal is carried by a jointless frame (the mocap body
`target`), so every map that reads that frame must take the value it would have with the frame
moved, without re-running the simulator. One rule per map type, in `_RULES`. A rule gets the map,
its old values y (..., dim) and a `FrameMove`, and returns the new values, or raises NotRelabelable
with the reason when y alone does not determine them. A map that does not read the moved frame
keeps its value.

The rules are exact: position-level maps move with the frame; orientation maps take its new
orientation; a map that also needs the pose of another frame reads it from `FrameMove.known`
(frames whose pose the goal carries, e.g. `tcp` in a pose goal) or from the world frame; a
`velocity(m)` keeps its value when m's Jacobian does not depend on the moved frame's pose (a
jointless frame has zero velocity, so y_dot = J_m q_dot changes only through J_m).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..exceptions import NotRelabelable
from .base import TaskMap
from .collision import AccumulatedCollisions, Distance
from .grasp import Oppose
from .gripper import GripperWidth
from .joint import JointLimits, JointState
from .orientation import Quaternion, QuaternionDiff, ScalarProduct, Vector
from .position import Position, PositionDiff, PositionRel
from .stack import Stack
from .suction import Suction
from .velocity import Velocity

#: The world frame's name in specs: its pose is known (identity) without being carried by the goal.
WORLD = "world"


class FramePose(NamedTuple):
    """A frame's world pose where it is known: pos (..., 3) and quat (..., 4) (w, x, y, z), or None."""

    pos: np.ndarray | None
    quat: np.ndarray | None


class FrameMove(NamedTuple):
    """A jointless frame moved from one pose to another (vectorised over leading axes).

    delta: (..., 3) world translation; old_quat, new_quat: (..., 4) world orientation before and
    after (the same array when it only translates); rotates: whether the orientation may change
    (False: the frame keeps the orientation it has in the scene); known: other frames' poses at the
    stored state.
    """

    frame: str
    delta: np.ndarray
    old_quat: np.ndarray
    new_quat: np.ndarray
    rotates: bool
    known: dict[str, FramePose]


def relabelled(task_map: TaskMap, y: np.ndarray, move: FrameMove) -> np.ndarray:
    """The values y (..., dim) of `task_map` with `move.frame` moved as `move` says; a new array.

    Raises:
        NotRelabelable: the map reads the frame and its new value is not determined by y and `move`
            (the message names the map and the reason).
    """
    y = np.array(y, dtype=np.float64)
    if move.frame not in task_map.frames:
        return y
    rule = _RULES.get(type(task_map))
    if rule is None:
        raise NotRelabelable(task_map.spec, move.frame, "no relabelling rule for this map type")
    return rule(task_map, y, move)


def check_relabelable(task_map: TaskMap, move: FrameMove) -> None:
    """Raises NotRelabelable unless every part of `task_map` can be relabelled for moves like `move`.

    The rules fail on the structure of a move (which frames are known, whether it rotates), never on
    its values, so one trial with `move`'s shapes decides for every move of that kind.
    """
    relabelled(task_map, np.zeros(task_map.dim), move)


def jacobian_invariant(task_map: TaskMap, move: FrameMove) -> bool:
    """Whether J of `task_map` is the same before and after `move` (what velocity maps need)."""
    if move.frame not in task_map.frames:
        return True
    if isinstance(task_map, Position | PositionDiff | Quaternion | QuaternionDiff | Vector):
        return True  # J reads only the other frame's Jacobian (the moved frame's is zero)
    if isinstance(task_map, ScalarProduct):
        return not move.rotates  # J = (a x b)^T (Jr_f - Jr_g) reads both axes
    if isinstance(task_map, PositionRel):
        # J = R_g^T (Jp_f - Jp_g + [p_f - p_g]x Jr_g): with f moved, [p_f - p_g]x Jr_g changes
        # unless g is fixed too; with g moved, J reads R_g.
        return task_map.f.name != move.frame and not move.rotates
    if isinstance(task_map, Stack):
        return all(jacobian_invariant(p, move) for p in task_map.parts)
    return False


# -- helpers -------------------------------------------------------------------------------------------
def quaternion_to_rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions q (..., 4) (w, x, y, z)."""
    w, x, y, z = np.moveaxis(np.asarray(q, dtype=np.float64), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _quat(name: str, task_map: TaskMap, move: FrameMove, new: bool = True) -> np.ndarray:
    """World orientation (..., 4) of frame `name`: the moved frame's, the world's, or a known one."""
    if name == move.frame:
        return move.new_quat if new else move.old_quat
    if name == WORLD:
        return np.array([1.0, 0.0, 0.0, 0.0])
    pose = move.known.get(name)
    if pose is None or pose.quat is None:
        raise NotRelabelable(
            task_map.spec,
            move.frame,
            f"it needs the orientation of frame {name!r}, which the goal does not carry",
        )
    return pose.quat


def _axis(quat: np.ndarray, axis: int) -> np.ndarray:
    return quaternion_to_rotation(quat)[..., :, axis]


# -- one rule per map type -------------------------------------------------------------------------
def _position(m: Position, y: np.ndarray, move: FrameMove) -> np.ndarray:
    return y + move.delta


def _position_diff(m: PositionDiff, y: np.ndarray, move: FrameMove) -> np.ndarray:
    sign = (move.frame == m.f.name) - (move.frame == m.g.name)
    return y + sign * move.delta


def _position_rel(m: PositionRel, y: np.ndarray, move: FrameMove) -> np.ndarray:
    f, g = m.f.name, m.g.name
    if f == g:
        return y  # R_g^T (p_f - p_f) = 0 wherever the frame goes
    if g == move.frame:  # y = R_g^T (p_f - p_g): world vector R_g y, shifted, seen from the new R_g
        v = np.einsum("...ij,...j->...i", quaternion_to_rotation(move.old_quat), y) - move.delta
        return np.einsum("...ji,...j->...i", quaternion_to_rotation(move.new_quat), v)
    if g == WORLD:
        return y + move.delta
    R_g = quaternion_to_rotation(_quat(g, m, move))
    return y + np.einsum("...ji,...j->...i", R_g, move.delta)


def _quaternion(m: Quaternion, y: np.ndarray, move: FrameMove) -> np.ndarray:
    if not move.rotates:
        return y
    return np.broadcast_to(move.new_quat, y.shape).copy()


def _quaternion_diff(m: QuaternionDiff, y: np.ndarray, move: FrameMove) -> np.ndarray:
    if not move.rotates:
        return y
    q_f, q_g = _quat(m.f.name, m, move), _quat(m.g.name, m, move)
    q_f, q_g = np.broadcast_arrays(q_f, q_g)
    s = np.where(np.sum(q_f * q_g, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)  # as QuaternionDiff.evaluate
    return np.broadcast_to(q_f - s * q_g, y.shape).copy()


def _vector(m: Vector, y: np.ndarray, move: FrameMove) -> np.ndarray:
    if not move.rotates:
        return y
    return np.broadcast_to(_axis(move.new_quat, m.axis), y.shape).copy()


def _scalar_product(m: ScalarProduct, y: np.ndarray, move: FrameMove) -> np.ndarray:
    if not move.rotates:
        return y
    a = _axis(_quat(m.f.name, m, move), m.axes[0])
    b = _axis(_quat(m.g.name, m, move), m.axes[1])
    return np.broadcast_to(np.sum(a * b, axis=-1, keepdims=True), y.shape).copy()


def _velocity(m: Velocity, y: np.ndarray, move: FrameMove) -> np.ndarray:
    if jacobian_invariant(m.map, move):
        return y
    raise NotRelabelable(
        m.spec, move.frame, f"the Jacobian of {m.map.spec} depends on the pose of that frame"
    )


def _stack(m: Stack, y: np.ndarray, move: FrameMove) -> np.ndarray:
    for part, span in zip(m.parts, m.slices.values()):
        y[..., span] = relabelled(part, y[..., span], move)
    return y


def _never(m: TaskMap, y: np.ndarray, move: FrameMove) -> np.ndarray:
    raise NotRelabelable(m.spec, move.frame, "its value depends on the frame's geometry, not only its pose")


def _unchanged(m: TaskMap, y: np.ndarray, move: FrameMove) -> np.ndarray:
    return y


_RULES: dict[type, Callable[..., np.ndarray]] = {
    Position: _position,
    PositionDiff: _position_diff,
    PositionRel: _position_rel,
    Quaternion: _quaternion,
    QuaternionDiff: _quaternion_diff,
    Vector: _vector,
    ScalarProduct: _scalar_product,
    Velocity: _velocity,
    Stack: _stack,
    Distance: _never,
    AccumulatedCollisions: _never,
    Oppose: _never,
    GripperWidth: _unchanged,
    Suction: _never,
    JointState: _unchanged,
    JointLimits: _unchanged,
}
