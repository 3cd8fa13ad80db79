"""The settling target every arm tsrl drives must meet: after a 5 cm step of the TCP's commanded point
from home, the TCP is within 1 mm of it from the end of the third 40 ms control period on, with no
physics warning (docs/robots.md). `settle` measures it on a compiled model, servos and all."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from .exceptions import InvalidConfig
from .ik import DlsSolver, IKOptions
from .kinematics import arm_dof_indices, arm_qpos_indices, name_to_id
from .robots import reset_to_key
from .servos import servos_on
from .taskmaps import Frame, Position, resolve_frame

#: The target: the step [m], the control period [s], the periods to settle in, the tolerance [m].
STEP, CONTROL_DT, PERIODS, TOLERANCE = 0.05, 0.04, 3, 1e-3
#: Control periods watched after the step (the TCP must stay within the tolerance until then).
WATCHED = 10
#: The step directions: +x, +y, +z, -x, -y, -z (world).
DIRECTIONS = np.vstack([np.eye(3), -np.eye(3)])
_AXES = ("+x", "+y", "+z", "-x", "-y", "-z")


@dataclass(frozen=True)
class StepResponse:
    """The TCP's response to one step of its commanded point.

    Attributes:
        direction: "+x", ..., "-z" (world axes).
        settled_error: distance [m] from the commanded point at the end of period PERIODS.
        worst_after: largest distance [m] from then until period WATCHED ends.
        overshoot: largest excursion [m] past the commanded point along the step (0 if none).
        warnings: MuJoCo warnings raised during the response (any kind).
    """

    direction: str
    settled_error: float
    worst_after: float
    overshoot: float
    warnings: int

    @property
    def ok(self) -> bool:
        return self.worst_after < TOLERANCE and self.warnings == 0


@dataclass(frozen=True)
class Settling:
    """Step responses in the six axis directions from home (those the TCP can move in).

    Attributes:
        responses: one per direction stepped.
        skipped: directions the TCP cannot move in at home (outside the span of its position
            Jacobian: a planar arm's out-of-plane axis).
    """

    responses: tuple[StepResponse, ...]
    skipped: tuple[str, ...] = ()

    @property
    def ok(self) -> bool:
        return bool(self.responses) and all(r.ok for r in self.responses)

    @property
    def worst(self) -> StepResponse:
        """The response with the largest error after settling."""
        return max(self.responses, key=lambda r: (r.warnings, r.worst_after))

    def summary(self) -> str:
        """One line: whether the target holds and the worst response."""
        if not self.responses:
            return "misses the settling target: the TCP cannot move along any axis at home"
        w = self.worst
        verdict = "meets" if self.ok else "misses"
        skipped = f"; {', '.join(self.skipped)} skipped (the TCP cannot move so)" if self.skipped else ""
        return (
            f"{verdict} the settling target ({STEP * 100:g} cm TCP step within {TOLERANCE * 1e3:g} mm after "
            f"{PERIODS} x {CONTROL_DT * 1e3:g} ms): worst {w.direction}: {w.worst_after * 1e3:.3f} mm, "
            f"overshoot {w.overshoot * 1e3:.2f} mm, {w.warnings} physics warnings{skipped}"
        )


def settle(
    model: mujoco.MjModel,
    joints: Sequence[str],
    tcp: str,
    home_q: np.ndarray,
    key: int | None = None,
    servos: Sequence[str] | None = None,
    directions: np.ndarray = DIRECTIONS,
) -> Settling:
    """Steps the TCP's commanded point by STEP along each direction (k, 3) from rest at home: keyframe
    `key` (the model's default state if None) with the joints at `home_q` (n,). `servos` names the
    joints' position servos in their order (None: the one servo found on each joint).

    The commanded point's joint targets come from tsrl's IK (a local solve of position(tcp) from home,
    with the null-space posture at home on a redundant arm); the servos get them at t = 0 and the
    physics runs WATCHED control periods (the other actuators as the keyframe sets them). A direction
    the TCP cannot move in at home (outside the span of its position Jacobian) is skipped.

    Raises:
        InvalidConfig: a joint without a position servo, or a commanded point the IK cannot reach.
    """
    found = servos_on(model, joints) if servos is None else [name_to_id(model, "actuator", s) for s in servos]
    missing = [j for j, a in zip(joints, found, strict=True) if a is None]
    if missing:
        raise InvalidConfig(f"joints {', '.join(missing)} have no position servo to settle with")
    ctrl = np.array(found, dtype=int)
    qpos = arm_qpos_indices(model, joints)
    frame = resolve_frame(model, tcp)
    posture = tuple(float(q) for q in home_q) if len(joints) > 6 else None
    solver = DlsSolver(
        model, Position(model, tcp), joints, IKOptions(tol=1e-6, max_iters=200, restarts=0, posture=posture)
    )
    data = mujoco.MjData(model)
    steps_per_period = round(CONTROL_DT / model.opt.timestep)
    responses, skipped = [], []
    span = _position_span(model, data, key, qpos, ctrl, home_q, frame, joints)
    for axis, direction in zip(_AXES, directions, strict=False):
        if np.linalg.norm(span @ direction) < 0.99:
            skipped.append(axis)
            continue
        _rest_at(model, data, key, qpos, ctrl, home_q)
        goal = _position(data, frame) + STEP * np.asarray(direction)
        ik_data = mujoco.MjData(model)
        ik_data.qpos[:] = data.qpos
        result = solver.solve(ik_data, goal)
        if not result.converged:
            raise InvalidConfig(
                f"the IK cannot reach the TCP {STEP * 100:g} cm {axis} of home (residual {result.error_norm:.2g} m)"
            )
        data.ctrl[ctrl] = result.q
        warnings_before = int(data.warning.number.sum())
        errors, along = [], []
        for _ in range(WATCHED * steps_per_period):
            mujoco.mj_step(model, data)
            offset = _position(data, frame) - goal
            errors.append(float(np.linalg.norm(offset)))
            along.append(float(offset @ direction))
        settled = PERIODS * steps_per_period - 1  # the last physics step of period PERIODS
        responses.append(
            StepResponse(
                axis,
                errors[settled],
                max(errors[settled:]),
                max(0.0, *along),
                int(data.warning.number.sum()) - warnings_before,
            )
        )
    return Settling(tuple(responses), tuple(skipped))


def _position_span(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    key: int | None,
    qpos: np.ndarray,
    ctrl: np.ndarray,
    home_q: np.ndarray,
    frame: Frame,
    joints: Sequence[str],
) -> np.ndarray:
    """The projector (3, 3) onto the directions the joints can move the TCP in at home: J J^+."""
    _rest_at(model, data, key, qpos, ctrl, home_q)
    jac = np.zeros((3, model.nv))
    if frame.kind == "site":
        mujoco.mj_jacSite(model, data, jac, None, frame.id)
    else:
        mujoco.mj_jacBody(model, data, jac, None, frame.id)
    J = jac[:, arm_dof_indices(model, joints)]
    return J @ np.linalg.pinv(J, rcond=1e-6)


def _rest_at(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    key: int | None,
    qpos: np.ndarray,
    ctrl: np.ndarray,
    home_q: np.ndarray,
) -> None:
    reset_to_key(model, data, key)
    data.qpos[qpos] = home_q
    data.ctrl[ctrl] = home_q
    mujoco.mj_forward(model, data)


def _position(data: mujoco.MjData, frame: Frame) -> np.ndarray:
    return (data.site_xpos[frame.id] if frame.kind == "site" else data.xpos[frame.id]).copy()
