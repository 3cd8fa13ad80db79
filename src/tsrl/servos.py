r"""Position servos for an arm whose model has none, with gains from the arm's own inertia (MjSpec).

Gains (docs/robots.md, "Servos tsrl adds"). Joint i's servo sees m_i = M_ii(q_home), the diagonal
entry of the joint-space inertia matrix at home [kg m^2 for a hinge, kg for a slide; MuJoCo's M
includes the joint's armature], and is critically damped at the bandwidth w = 2 pi f [rad/s]:

.. math:: k_{p,i} = m_i w^2, \qquad k_{v,i} = 2 m_i w - d_i

(d_i: the joint's own damping, which MuJoCo applies as well), so that the joint alone follows
m_i e'' + 2 m_i w e' + m_i w^2 e = 0: a step's error decays as (1 + w t) e^{-w t}, below 2 % (1 mm of
a 5 cm step) after three 40 ms control periods where f > 7.7 Hz. The diagonal leaves out the coupling
between joints: on Gymnasium-Robotics' Fetch arm some coupled modes are damped at only 0.7 of
critical, and a 5 cm step settles to 2.0 mm at 10 Hz, 0.92 mm at 12 Hz, 0.18 mm at 15 Hz: the
default. `tsrl.settling` measures the real response.

Stability: servos are added with the implicitfast integrator (an implicit one is kept), which treats
the damping kv + d implicitly; the stiffness stays explicit. A bandwidth is accepted when the one-step
map of the arm linearised at home, as that integrator computes it, has spectral radius < 1
(`step_map_radius`); `max_stable_bandwidth` is the largest such bandwidth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from .kinematics import arm_dof_indices, arm_qpos_indices, joint_ids

#: Bandwidth [Hz] of the servos tsrl adds, unless the robot file gives `servo_bandwidth`.
DEFAULT_BANDWIDTH_HZ = 15.0
#: Control range [rad] of an added servo on a hinge without limits: tsrl's default range.
DEFAULT_HINGE_RANGE = (-2 * math.pi, 2 * math.pi)
#: Integrators that treat the servos' damping implicitly.
IMPLICIT_INTEGRATORS = (
    int(mujoco.mjtIntegrator.mjINT_IMPLICITFAST),
    int(mujoco.mjtIntegrator.mjINT_IMPLICIT),
)

_TRN_JOINT = int(mujoco.mjtTrn.mjTRN_JOINT)
_BIAS_AFFINE = int(mujoco.mjtBias.mjBIAS_AFFINE)


def servo_name(joint: str) -> str:
    """The name of the servo tsrl adds to `joint`."""
    return f"{joint}:servo"


@dataclass(frozen=True)
class ServoGains:
    """A position servo on one joint: force kp (ctrl - q) - kv qdot, ctrl within ctrlrange.

    Attributes:
        joint: the joint's name; inertia: m_i = M_ii at home [kg m^2 or kg];
        kp [N m/rad or N/m], kv [N m s/rad or N s/m]; ctrlrange: (lo, hi) [rad or m].
    """

    joint: str
    inertia: float
    kp: float
    kv: float
    ctrlrange: tuple[float, float]


def is_position_servo(model: mujoco.MjModel, a: int) -> bool:
    """Whether actuator a is a position servo: force kp (ctrl - q) (- kv qdot), MJCF's <position>."""
    kp = model.actuator_gainprm[a, 0]
    return int(model.actuator_biastype[a]) == _BIAS_AFFINE and kp > 0 and model.actuator_biasprm[a, 1] == -kp


def joint_actuators(model: mujoco.MjModel, joint: int) -> list[int]:
    """Ids of the actuators whose transmission is joint `joint` (its id)."""
    return [
        a
        for a in range(model.nu)
        if int(model.actuator_trntype[a]) == _TRN_JOINT and int(model.actuator_trnid[a, 0]) == joint
    ]


def servos_on(model: mujoco.MjModel, joints: Sequence[str]) -> tuple[int | None, ...]:
    """Per joint, the id of the one position servo that drives it; None where it has none (or several)."""
    out: list[int | None] = []
    for j in joint_ids(model, joints):
        servos = [a for a in joint_actuators(model, j) if is_position_servo(model, a)]
        out.append(servos[0] if len(servos) == 1 else None)
    return tuple(out)


def home_inertia(model: mujoco.MjModel, joints: Sequence[str], home_q: np.ndarray) -> np.ndarray:
    """The joint-space inertia matrix of the joints at home, (n, n) [kg m^2, kg], armature included;
    the other joints at qpos0."""
    data = mujoco.MjData(model)
    data.qpos[arm_qpos_indices(model, joints)] = home_q
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    dofs = arm_dof_indices(model, joints)
    return full[np.ix_(dofs, dofs)]


def servo_gains(
    model: mujoco.MjModel,
    joints: Sequence[str],
    home_q: np.ndarray,
    bandwidth_hz: float,
    ctrlranges: Sequence[tuple[float, float]],
) -> tuple[ServoGains, ...]:
    """Critically damped gains at `bandwidth_hz` from the diagonal of M(q_home) (module docstring)."""
    w = 2 * math.pi * bandwidth_hz
    inertia = np.diag(home_inertia(model, joints, home_q))
    damping = model.dof_damping[arm_dof_indices(model, joints)]
    return tuple(
        ServoGains(name, float(m), float(m * w * w), float(max(2 * m * w - d, 0.0)), (float(lo), float(hi)))
        for name, m, d, (lo, hi) in zip(joints, inertia, damping, ctrlranges, strict=True)
    )


def step_map_radius(
    model: mujoco.MjModel, joints: Sequence[str], home_q: np.ndarray, gains: Sequence[ServoGains]
) -> float:
    """Spectral radius of one physics step of the arm, linearised at home, under its servos.

    Semi-implicit Euler with implicit damping (implicitfast): with A = (M + h B)^-1, B = diag(kv + d),
    K = diag(kp + joint stiffness), h the timestep,
    v' = v - h A (K q + B v),  q' = q + h v'.  Stable where the radius is < 1.
    """
    n, h = len(joints), model.opt.timestep
    M = home_inertia(model, joints, home_q)
    dofs = arm_dof_indices(model, joints)
    stiffness = model.jnt_stiffness[list(joint_ids(model, joints))]
    K = np.diag(np.array([g.kp for g in gains]) + stiffness)
    B = np.diag(np.array([g.kv for g in gains]) + model.dof_damping[dofs])
    A = np.linalg.inv(M + h * B)
    velocity = np.hstack([-h * A @ K, np.eye(n) - h * A @ B])  # v' from (q, v)
    position = np.hstack([np.eye(n), np.zeros((n, n))]) + h * velocity  # q' = q + h v'
    return float(np.max(np.abs(np.linalg.eigvals(np.vstack([position, velocity])))))


def max_stable_bandwidth(
    model: mujoco.MjModel,
    joints: Sequence[str],
    home_q: np.ndarray,
    ctrlranges: Sequence[tuple[float, float]],
) -> float:
    """The largest bandwidth [Hz] (to 0.1 %) whose servos keep `step_map_radius` below 1."""

    def stable(f: float) -> bool:
        gains = servo_gains(model, joints, home_q, f, ctrlranges)
        return step_map_radius(model, joints, home_q, gains) < 1.0

    lo, hi = 0.0, 1.0
    while stable(hi):
        lo, hi = hi, 2 * hi
    while hi - lo > 1e-3 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo


def add_servos(spec: mujoco.MjSpec, gains: Sequence[ServoGains]) -> tuple[str, ...]:
    """Adds one position servo per entry of `gains` to `spec` (named `servo_name(joint)`); switches an
    explicit integrator to implicitfast; every keyframe's servo targets are its joint positions.

    Returns the servos' names, in the order of `gains`.
    """
    if int(spec.option.integrator) not in IMPLICIT_INTEGRATORS:
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    model = spec.compile()  # qpos addresses of the joints, for the keyframes below
    key_targets = []
    for key in spec.keys:
        qpos = np.array(key.qpos) if len(key.qpos) else model.qpos0
        key_targets.append(
            [qpos[model.jnt_qposadr[model.joint(g.joint).id]] for g in gains],
        )
    names = []
    for g in gains:
        actuator = spec.add_actuator(name=servo_name(g.joint), target=g.joint)
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        actuator.set_to_position(kp=g.kp, kv=g.kv)
        actuator.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.ctrlrange = list(g.ctrlrange)
        names.append(actuator.name)
    for key, targets in zip(spec.keys, key_targets, strict=True):
        ctrl = list(key.ctrl) if len(key.ctrl) else [0.0] * model.nu
        key.ctrl = ctrl + [float(t) for t in targets]
    return tuple(names)


def add_gravity_compensation(spec: mujoco.MjSpec, joints: Sequence[str]) -> int:
    """Gravity compensation of every body the joints move (gravcomp = 1 on the first joint's body and
    all below it), applied through the joints' actuators (actuatorgravcomp). Returns the body count."""
    top = spec.joint(joints[0]).parent
    bodies = [top, *top.find_all(mujoco.mjtObj.mjOBJ_BODY)]
    for body in bodies:
        body.gravcomp = 1.0
    for joint in joints:
        spec.joint(joint).actgravcomp = True
    return len(bodies)
