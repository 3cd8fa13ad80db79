"""Joint speed and acceleration limits of the built-in arms, as the deployment contract records them.

Speeds are the arms' published limits (tsrl.assets.ur5e, tsrl.assets.panda). Accelerations: the
Panda's are Franka's published joint acceleration limits (Franka Control Interface documentation,
"Robot and interface specifications": 15, 7.5, 10, 12.5, 15, 20, 20 rad/s^2); Universal Robots
publish none for the UR5e's joints, so 15 rad/s^2 on every joint is tsrl's setting, not a UR figure
(docs/deploy.md). `tsrl export --max-joint-speed/--max-joint-acceleration` overrides both, and is
required for an arm that is not built in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..assets import panda, ur5e
from ..exceptions import InvalidConfig

#: name -> (speeds [rad/s], accelerations [rad/s^2], where they come from), one per joint.
BUILTIN_LIMITS: dict[str, tuple[tuple[float, ...], tuple[float, ...], str]] = {
    "ur5e": (
        (float(ur5e.MAX_JOINT_SPEED),) * 6,
        (15.0,) * 6,
        "speed: UR5e technical specifications (180 deg/s); acceleration: tsrl's setting (UR publishes none)",
    ),
    "panda": (
        tuple(float(v) for v in panda.MAX_JOINT_SPEEDS),
        (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0),
        "speed and acceleration: Franka's published joint limits",
    ),
}
# The arms with the Franka Hand have their arm's joints and limits (the hand's width is its own command).
BUILTIN_LIMITS["panda_gripper"] = BUILTIN_LIMITS["panda"]
BUILTIN_LIMITS["ur5e_gripper"] = BUILTIN_LIMITS["ur5e"]


def robot_limits(
    robot: str,
    n_joints: int,
    max_joint_speed: Sequence[float] | None = None,
    max_joint_acceleration: Sequence[float] | None = None,
) -> dict[str, object]:
    """The contract's limits for `robot` (a built-in name or a robot file): the built-in values unless
    given (one value for every joint, or one per joint).

    Raises:
        InvalidConfig: a robot that is not built in without both limits; a limit that is not > 0 or
            not one value or n_joints values.
    """
    builtin = BUILTIN_LIMITS.get(robot)
    if builtin is None and (max_joint_speed is None or max_joint_acceleration is None):
        raise InvalidConfig(
            f"robot {robot!r} is not built in ({', '.join(BUILTIN_LIMITS)}): give its limits with "
            "--max-joint-speed and --max-joint-acceleration (rad/s, rad/s^2; one value or one per joint)"
        )
    speed = _per_joint("--max-joint-speed", max_joint_speed, n_joints) if max_joint_speed else None
    accel = (
        _per_joint("--max-joint-acceleration", max_joint_acceleration, n_joints)
        if max_joint_acceleration
        else None
    )
    source = builtin[2] if builtin is not None else ""
    if speed is not None or accel is not None:
        source = "given at export" + (f" (others: {source})" if builtin is not None else "")
    return {
        "max_joint_speed": list(speed if speed is not None else builtin[0]),  # type: ignore[index]
        "max_joint_acceleration": list(accel if accel is not None else builtin[1]),  # type: ignore[index]
        "limits_source": source,
    }


def _per_joint(name: str, values: Sequence[float], n: int) -> tuple[float, ...]:
    v = tuple(float(x) for x in values)
    if len(v) == 1:
        v = v * n
    if len(v) != n or not all(math.isfinite(x) and x > 0 for x in v):
        raise InvalidConfig(f"{name} must be one value or {n} values, each > 0; got {list(values)}")
    return v
