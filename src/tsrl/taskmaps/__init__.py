"""Task maps phi: q -> (y, J) named after RAI feature symbols, their stack and the spec parser."""

from .base import TaskMap, TaskMapValue
from .collision import AccumulatedCollisions, Distance
from .frames import Frame, FrameCache, resolve_frame
from .grasp import Oppose
from .gripper import GripperWidth
from .joint import JointLimits, JointState
from .orientation import Quaternion, QuaternionDiff, ScalarProduct, Vector
from .position import Position, PositionDiff, PositionRel
from .spec import TASK_MAPS, known_maps, parse_spec
from .stack import Stack
from .suction import Suction
from .velocity import Velocity

__all__ = (
    "TASK_MAPS",
    "AccumulatedCollisions",
    "Distance",
    "Frame",
    "FrameCache",
    "GripperWidth",
    "JointLimits",
    "JointState",
    "Oppose",
    "Position",
    "PositionDiff",
    "PositionRel",
    "Quaternion",
    "QuaternionDiff",
    "ScalarProduct",
    "Stack",
    "Suction",
    "TaskMap",
    "TaskMapValue",
    "Vector",
    "Velocity",
    "known_maps",
    "parse_spec",
    "resolve_frame",
)
