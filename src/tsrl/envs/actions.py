"""Action modes: how an agent's action in [-1, 1]^k becomes joint targets (through IK or directly)."""

from __future__ import annotations

from dataclasses import dataclass

#: Accepted action modes and what they mean.
ACTION_MODES: dict[str, str] = {
    "taskspace": "TCP position step (3), cup held pointing down by the IK",
    "taskspace_orient": "TCP position step (3) + target scalar products x.x, y.y, z.z of world and TCP axes (3)",
    "joint": "joint target steps (6), no IK (the end-to-end baseline)",
}


@dataclass(frozen=True)
class ActionConfig:
    """Scales of an action mode.

    Attributes:
        mode: one of ACTION_MODES.
        max_tcp_step: metres the TCP target moves per step at |a| = 1 (taskspace modes).
        max_joint_step: radians a joint target moves per step at |a| = 1 (joint mode); the default
            is the UR5e's 180 deg/s over one 40 ms control period.
        suction: whether a last action dimension commands the suction cup (on above 0).
    """

    mode: str = "taskspace"
    max_tcp_step: float = 0.05
    max_joint_step: float = 0.04 * 3.141592653589793
    suction: bool = False

    @property
    def dim(self) -> int:
        base = {"taskspace": 3, "taskspace_orient": 6, "joint": 6}[self.mode]
        return base + int(self.suction)

    @property
    def ik_spec(self) -> str | None:
        """Task maps whose target values the IK meets, or None for joint actions."""
        if self.mode == "taskspace":
            # The cup points down: TCP z axis = -world z (equivalently scalarProductZZ(world, tcp) = -1,
            # but the axis form has a full-rank Jacobian at the target, so the IK converges fast).
            return "position(tcp), vectorZ(tcp)"
        if self.mode == "taskspace_orient":
            return "position(tcp), scalarProductXX(world, tcp), scalarProductYY(world, tcp), scalarProductZZ(world, tcp)"
        return None
