"""A robot's model made ready for a task, on its MjSpec before it is compiled (docs/robots.md).

`prepare_spec(spec, robot, where)`, in this order, and nothing in the spec changes until every check
has passed (a bad robot file builds nothing):

1. every name of the robot file is checked against the model: `joints`, `tcp`, `home`, `actuators`,
   `suction`, `drop_equalities`; the joints must be a chain from the base to the TCP, base to tip;
2. `drop_equalities` are removed; an active equality constraint that still acts on the controlled
   joints (a weld to a mocap body, say) pins the arm and is an error naming it;
3. servos: the robot file's `actuators`, else the model's own position servo on each joint, else
   tsrl adds them (tsrl.servos: gains from the arm's inertia at home, critically damped at
   `servo_bandwidth`, implicitfast); other actuators on those joints (torque motors) stay at zero
   and are reported once; servos on some joints but not all are an error;
4. gravity compensation of the arm's bodies where tsrl adds the servos (or `gravity_compensation`);
5. a `home` given as joint values becomes the keyframe `tsrl.robots.HOME_KEY`.

Errors are one InvalidConfig line naming the robot file, the key and what is accepted; what tsrl
changed or assumed is a one-line `RobotNotice` warning (and in `PreparedArm.notices`).
"""

from __future__ import annotations

import functools
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import mujoco
import numpy as np

from .assets import SCENES, scene_path
from .exceptions import InvalidConfig, ModelLoadError, TsrlError
from .kinematics import arm_dof_indices, arm_qpos_indices, controlled_joints, joint_limits, name_to_id
from .model_files import resolve_model_path
from .robots import HOME_KEY, ROBOTS, Robot
from .servos import (
    DEFAULT_BANDWIDTH_HZ,
    DEFAULT_HINGE_RANGE,
    ServoGains,
    add_gravity_compensation,
    add_servos,
    is_position_servo,
    joint_actuators,
    max_stable_bandwidth,
    servo_gains,
    servo_name,
    servos_on,
    step_map_radius,
)
from .taskmaps import resolve_frame

T = TypeVar("T")
_HINGE, _SLIDE = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
_EQUALITY = int(mujoco.mjtConstraint.mjCNSTR_EQUALITY)
_EQ_KINDS = {int(v): k.removeprefix("mjEQ_").lower() for k, v in mujoco.mjtEq.__members__.items()}


class RobotNotice(UserWarning):
    """What tsrl changed in, or assumed about, a robot's model (one line, shown once)."""


@dataclass(frozen=True)
class PreparedArm:
    """What `prepare_spec` found and did.

    Attributes:
        servos: the position servos of the joints, in their order (the model's own, or added).
        added: the gains of the servos tsrl added (empty where the model has its own).
        bandwidth_hz: the bandwidth of the added servos [Hz]; None where none were added.
        gravity_compensation: whether tsrl turned on gravity compensation of the arm's bodies.
        base: the robot's base body (`arm_base`).
        dropped: the equality constraints removed (descriptions).
        notices: the one-line notices issued.
    """

    servos: tuple[str, ...]
    added: tuple[ServoGains, ...]
    bandwidth_hz: float | None
    gravity_compensation: bool
    base: str
    dropped: tuple[str, ...]
    notices: tuple[str, ...]


def robot_label(robot: str | Path) -> str:
    """How errors name a robot: its file's path, or `robot 'ur5e'` for a built-in one."""
    return f"robot {robot!r}" if isinstance(robot, str) and robot in ROBOTS else str(robot)


def model_spec(name: str, base: Path | None = None, key: str = "model") -> mujoco.MjSpec:
    """The MjSpec of a built-in scene, a `pkg://` model or an MJCF/URDF file (relative to `base`).

    Raises:
        InvalidConfig: no such scene or file; ModelLoadError: MuJoCo cannot read the file.
    """
    if name in SCENES:
        path = scene_path(name)
    else:
        path = resolve_model_path(name, base, key)
        if path.suffix.lower() not in (".xml", ".urdf") or not path.is_file():
            raise InvalidConfig(
                f"{key} = {name!r}: neither a built-in scene ({', '.join(SCENES)}) nor an existing "
                "model file (.xml, .urdf)"
            )
    try:
        return mujoco.MjSpec.from_file(str(path))
    except ValueError as err:
        raise ModelLoadError(f"{key} = {str(path)!r}: MuJoCo could not read it: {_one_line(err)}") from None


def compile_spec(spec: mujoco.MjSpec, where: str) -> mujoco.MjModel:
    """spec.compile(), a MuJoCo error as one ModelLoadError line naming `where`."""
    try:
        model = spec.compile()
    except ValueError as err:
        raise ModelLoadError(f"{where}: MuJoCo could not compile the model: {_one_line(err)}") from None
    _check_options(model, where)
    return model


#: The real-valued <option> attributes of a model (MuJoCo compiles NaN and inf in them without a word).
_REAL_OPTIONS = (
    "timestep", "impratio", "tolerance", "ls_tolerance", "noslip_tolerance", "ccd_tolerance", "gravity",
    "wind", "magnetic", "density", "viscosity", "o_margin", "o_solref", "o_solimp", "o_friction",
)  # fmt: skip


def _check_options(model: mujoco.MjModel, where: str) -> None:
    """Raises ModelLoadError (one line) where an <option> number is NaN or infinite, or timestep <= 0:
    the simulation would run on garbage or fail deep inside the first check that uses it."""
    for name in _REAL_OPTIONS:
        value = np.atleast_1d(getattr(model.opt, name))
        if not np.all(np.isfinite(value)):
            shown = " ".join(f"{v:g}" for v in value)
            raise ModelLoadError(f'{where}: the model\'s <option {name}="{shown}">; accepted: finite numbers')
    if model.opt.timestep <= 0:
        raise ModelLoadError(
            f'{where}: the model\'s <option timestep="{model.opt.timestep:g}">; accepted: > 0 s'
        )


def load_robot_model(robot: Robot, where: str) -> tuple[mujoco.MjModel, PreparedArm]:
    """The robot's own model file, prepared (`prepare_spec`) and compiled."""
    spec = model_spec(robot.model)
    prepared = prepare_spec(spec, robot, where)
    return compile_spec(spec, where), prepared


def prepare_spec(spec: mujoco.MjSpec, robot: Robot, where: str) -> PreparedArm:
    """Makes the arm in `spec` ready for a task, in place (module docstring); `where` names the robot
    file in messages.

    Raises:
        InvalidConfig: one line naming `where`, the key and what is accepted.
        ModelLoadError: the spec does not compile.
    """
    probe = compile_spec(spec, where)
    check = _Checker(where)
    joints = check("joints", lambda: controlled_joints(probe, robot.joints))
    tcp = check("tcp", lambda: resolve_frame(probe, robot.tcp))
    _check_chain(probe, joints, tcp.body, robot.tcp, where)
    home_q = check("home", lambda: _home_q(probe, robot))
    for key, actuator in (("suction", robot.suction), ("gripper", robot.gripper)):
        if actuator is not None:
            check(key, functools.partial(name_to_id, probe, "actuator", actuator))
    base = check("base", lambda: arm_base(probe, robot))
    drop = _equalities_to_drop(spec, robot.drop_equalities, where)
    if drop:  # the pin check below sees the model without them
        trial = spec.copy()
        _drop(trial, drop)
        probe = compile_spec(trial, where)
    _check_no_pins(probe, joints, home_q, where)

    own = _own_servos(probe, robot, joints, where)
    notices: list[str] = []
    added: tuple[ServoGains, ...] = ()
    bandwidth = None
    if own is None:
        bandwidth = DEFAULT_BANDWIDTH_HZ if robot.servo_bandwidth is None else robot.servo_bandwidth
        added = _added_gains(probe, joints, home_q, bandwidth, where, notices)
    elif robot.servo_bandwidth is not None:
        raise InvalidConfig(
            f"{where}: servo_bandwidth = {robot.servo_bandwidth:g}: the model has its own servos "
            f"({', '.join(own)}); accepted only where tsrl adds them (no servos on the joints)"
        )
    gravity = bool(added) if robot.gravity_compensation is None else robot.gravity_compensation

    # Every check has passed: change the spec.
    dropped = _drop(spec, drop)
    if own is None:
        motors = sorted({probe.actuator(a).name or f"#{a}" for j in joints for a in _actuators(probe, j)})
        if motors:
            notices.append(
                f"{where}: actuators {', '.join(motors)} on the controlled joints are not position "
                "servos; tsrl leaves them at zero and adds a position servo per joint"
            )
            _zero_in_keyframes(spec, probe, [a for j in joints for a in _actuators(probe, j)])
        servos = add_servos(spec, added)
    else:
        servos = own
        if not robot.actuators:  # found on the model: an unnamed one gets tsrl's name (Robot.bind finds it)
            for name, a in zip(own, servos_on(probe, joints), strict=True):
                if a is not None and not probe.actuator(a).name:
                    spec.actuators[a].name = name
    if gravity:
        add_gravity_compensation(spec, joints)
    if robot.home is not None and not isinstance(robot.home, str):
        if own is None:  # tsrl's servos come after the model's actuators
            ids: Sequence[int] = range(probe.nu, probe.nu + len(servos))
        elif robot.actuators:
            ids = [name_to_id(probe, "actuator", s) for s in servos]
        else:
            ids = [a for a in servos_on(probe, joints) if a is not None]
        _add_home_key(spec, probe, joints, home_q, ids, len(added))
    for notice in notices:
        warnings.warn(notice, RobotNotice, stacklevel=2)
    return PreparedArm(
        servos=tuple(servos),
        added=added,
        bandwidth_hz=bandwidth,
        gravity_compensation=gravity,
        base=base,
        dropped=tuple(dropped),
        notices=tuple(notices),
    )


def arm_base(model: mujoco.MjModel, robot: Robot) -> str:
    """The robot's base body: its `base`, checked, else the body its first joint's body hangs from
    ("world" for an arm mounted on the world).

    Raises:
        UnknownName: a `base` the model has no body of that name for (the message lists the bodies).
    """
    if robot.base is not None:
        name_to_id(model, "body", robot.base)
        return robot.base
    first = int(model.jnt_bodyid[name_to_id(model, "joint", robot.joints[0])])
    return model.body(int(model.body_parentid[first])).name or "world"


# -- checks ------------------------------------------------------------------------------------------
class _Checker:
    """Runs a check of one robot-file key; its error becomes one line naming the file and the key."""

    def __init__(self, where: str):
        self.where = where

    def __call__(self, key: str, check: Callable[[], T]) -> T:
        try:
            return check()
        except TsrlError as err:
            raise InvalidConfig(f"{self.where}: {key}: {err}") from None


def _check_chain(model: mujoco.MjModel, joints: Sequence[str], tcp_body: int, tcp: str, where: str) -> None:
    """The joints lie on the path from the world to the TCP's body, base to tip."""
    path = [tcp_body]
    while path[-1] > 0:
        path.append(int(model.body_parentid[path[-1]]))
    depth = {b: i for i, b in enumerate(reversed(path))}  # the world 0, the TCP's body deepest
    chain = [model.joint(j).name for j in range(model.njnt) if int(model.jnt_bodyid[j]) in depth]
    accepted = f"accepted: joints on the chain from the base to the TCP, base to tip: {', '.join(chain)}"
    last = -1
    for name in joints:
        body = int(model.jnt_bodyid[model.joint(name).id])
        if body not in depth:
            raise InvalidConfig(f"{where}: joints: {name!r} does not move the TCP {tcp!r}; {accepted}")
        if depth[body] < last:
            raise InvalidConfig(f"{where}: joints: {name!r} comes after a joint below it; {accepted}")
        last = depth[body]


def _home_q(model: mujoco.MjModel, robot: Robot) -> np.ndarray:
    """The home positions (n,), checked: a keyframe the model has, or finite values within the limits."""
    if robot.home is None or isinstance(robot.home, str):
        return robot.home_q(model)
    q = np.asarray(robot.home, dtype=np.float64)
    if q.shape != (len(robot.joints),) or not np.isfinite(q).all():
        raise InvalidConfig(
            f"{list(robot.home)} ({len(robot.home)} values); accepted: a keyframe's name or "
            f"{len(robot.joints)} finite joint values"
        )
    limits = joint_limits(model, robot.joints)
    outside = [
        f"{j} = {v:g} outside [{lo:g}, {hi:g}]"
        for j, v, (lo, hi) in zip(robot.joints, q, limits, strict=True)
        if not lo <= v <= hi
    ]
    if outside:
        raise InvalidConfig(f"{', '.join(outside)}; accepted: values within the joints' ranges")
    return q


def _describe(e: mujoco.MjsEquality) -> str:
    kind = _EQ_KINDS.get(int(e.type), "equality")
    name = repr(e.name) if e.name else "(unnamed)"
    between = f" between {e.name1} and {e.name2}" if e.name2 else f" on {e.name1}"
    return f"{kind} {name}{between}"


def _equalities_to_drop(spec: mujoco.MjSpec, names: Sequence[str], where: str) -> list[int]:
    """Indices in spec.equalities of those `drop_equalities` names: each entry an equality's name or a
    name it connects."""
    equalities = list(spec.equalities)
    drop: list[int] = []
    for entry in names:
        hits = [i for i, e in enumerate(equalities) if entry in (e.name, e.name1, e.name2)]
        if not hits:
            known = "; ".join(_describe(e) for e in equalities) or "none"
            raise InvalidConfig(
                f"{where}: drop_equalities: no equality constraint is named {entry!r} or connects it; "
                f"accepted: a constraint's name or a body/joint it connects (the model's: {known})"
            )
        drop += [i for i in hits if i not in drop]
    return drop


def _drop(spec: mujoco.MjSpec, drop: Sequence[int]) -> list[str]:
    """Removes the equalities at indices `drop` of spec.equalities (a copy of a spec keeps their order);
    returns their descriptions."""
    equalities = list(spec.equalities)
    removed = [equalities[i] for i in drop]
    described = [_describe(e) for e in removed]
    for e in removed:
        spec.delete(e)
    return described


def _check_no_pins(model: mujoco.MjModel, joints: Sequence[str], home_q: np.ndarray, where: str) -> None:
    """No active equality constraint acts on the controlled joints (its Jacobian rows at home)."""
    if model.neq == 0:
        return
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE  # a probe: efc_J as (nefc, nv)
    data = mujoco.MjData(model)
    data.qpos[arm_qpos_indices(model, joints)] = home_q
    mujoco.mj_forward(model, data)
    rows = np.flatnonzero(data.efc_type[: data.nefc] == _EQUALITY)
    J = data.efc_J[: data.nefc * model.nv].reshape(data.nefc, model.nv)
    dofs = arm_dof_indices(model, joints)
    pinned = sorted({int(data.efc_id[r]) for r in rows if np.abs(J[r, dofs]).max() > 1e-9})
    if pinned:
        spec_eqs = [_eq_description(model, i) for i in pinned]
        i = pinned[0]
        name = model.equality(i).name or _eq_object(model, i, 1)
        raise InvalidConfig(
            f"{where}: {'; '.join(spec_eqs)} acts on the controlled joints and pins the arm; accepted: "
            f'drop_equalities = ["{name}"] (removes it) or a model without it'
        )


def _eq_object(model: mujoco.MjModel, i: int, which: int) -> str:
    obj = int(model.eq_obj1id[i] if which == 1 else model.eq_obj2id[i])
    objtype = int(model.eq_objtype[i])
    return mujoco.mj_id2name(model, objtype, obj) or ("world" if obj == 0 else f"#{obj}")


def _eq_description(model: mujoco.MjModel, i: int) -> str:
    kind = _EQ_KINDS.get(int(model.eq_type[i]), "equality")
    name = repr(model.equality(i).name) if model.equality(i).name else "(unnamed)"
    return f"{kind} {name} between {_eq_object(model, i, 1)} and {_eq_object(model, i, 2)}"


def _own_servos(
    model: mujoco.MjModel, robot: Robot, joints: Sequence[str], where: str
) -> tuple[str, ...] | None:
    """The robot's servos: its `actuators` (checked), else the model's one per joint; None: none at all."""
    if robot.actuators:
        if len(robot.actuators) != len(joints):
            raise InvalidConfig(
                f"{where}: actuators: {len(robot.actuators)} for {len(joints)} joints; accepted: one "
                "position servo per joint, in the joints' order, or none (tsrl adds them)"
            )
        for actuator, joint in zip(robot.actuators, joints, strict=True):
            a = _Checker(where)("actuators", functools.partial(name_to_id, model, "actuator", actuator))
            if a not in joint_actuators(model, model.joint(joint).id) or not is_position_servo(model, a):
                raise InvalidConfig(
                    f"{where}: actuators: {actuator!r} is not a position servo of joint {joint!r}; "
                    "accepted: one position servo (MJCF <position>) per joint, in the joints' order"
                )
        return tuple(robot.actuators)
    found = servos_on(model, joints)
    if all(a is None for a in found):
        return None
    missing = [j for j, a in zip(joints, found, strict=True) if a is None]
    if missing:
        have = [j for j, a in zip(joints, found, strict=True) if a is not None]
        raise InvalidConfig(
            f"{where}: actuators: the model has position servos on {', '.join(have)} but not on "
            f"{', '.join(missing)}; accepted: a servo on every controlled joint, or on none (tsrl adds them)"
        )
    return tuple(
        model.actuator(a).name or servo_name(j) for j, a in zip(joints, found, strict=True) if a is not None
    )


def _added_gains(
    model: mujoco.MjModel,
    joints: Sequence[str],
    home_q: np.ndarray,
    bandwidth: float,
    where: str,
    notices: list[str],
) -> tuple[ServoGains, ...]:
    """Gains of the servos tsrl adds, their control ranges (tsrl's default on hinges without limits)
    and the check that the timestep holds them."""
    if (
        isinstance(bandwidth, bool)
        or not isinstance(bandwidth, int | float)
        or not math.isfinite(bandwidth)
        or bandwidth <= 0
    ):
        raise InvalidConfig(f"{where}: servo_bandwidth = {bandwidth!r}; accepted: a number of Hz > 0")
    ranges, unlimited = [], []
    for name, (lo, hi) in zip(joints, joint_limits(model, joints), strict=True):
        if np.isfinite(lo):
            ranges.append((float(lo), float(hi)))
        elif int(model.jnt_type[model.joint(name).id]) == _HINGE:
            ranges.append(DEFAULT_HINGE_RANGE)
            unlimited.append(name)
        else:
            raise InvalidConfig(
                f"{where}: joints: slide joint {name!r} has no range, so no servo range; accepted: "
                "slide joints with limits (MJCF range, URDF <limit lower upper>)"
            )
    gains = servo_gains(model, joints, home_q, bandwidth, ranges)
    radius = step_map_radius(model, joints, home_q, gains)
    if not radius < 1.0:
        top = max_stable_bandwidth(model, joints, home_q, ranges)
        raise InvalidConfig(
            f"{where}: servo_bandwidth = {bandwidth:g} Hz: the timestep {model.opt.timestep:g} s cannot "
            f"hold it (one physics step of the arm at home grows by {radius:.3g}); accepted: < {top:.3g} Hz"
        )
    if unlimited:
        notices.append(
            f"{where}: hinge joints {', '.join(unlimited)} have no range; tsrl's servos keep them within "
            "its default +-2 pi (jointLimits still refuses them)"
        )
    return gains


def _actuators(model: mujoco.MjModel, joint: str) -> list[int]:
    return joint_actuators(model, model.joint(joint).id)


def _zero_in_keyframes(spec: mujoco.MjSpec, model: mujoco.MjModel, actuators: Sequence[int]) -> None:
    for key in spec.keys:
        if len(key.ctrl):
            ctrl = list(key.ctrl)
            for a in actuators:
                ctrl[a] = 0.0
            key.ctrl = ctrl


def _add_home_key(
    spec: mujoco.MjSpec,
    model: mujoco.MjModel,
    joints: Sequence[str],
    home_q: np.ndarray,
    servo_ids: Sequence[int],
    added: int,
) -> None:
    """The keyframe HOME_KEY: the joints at home, their servos' targets there, every other hinge or
    slide joint at qpos0 clipped into its range (a model's qpos0 may lie outside a joint's range: the
    limit would then move it, and the arm with it, at the start of every episode). `servo_ids`: the
    servos' actuator ids once compiled; `added`: how many actuators tsrl adds after the model's."""
    qpos = model.qpos0.copy()
    for j in range(model.njnt):
        if model.jnt_limited[j] and int(model.jnt_type[j]) in (_HINGE, _SLIDE):
            a = model.jnt_qposadr[j]
            qpos[a] = np.clip(qpos[a], *model.jnt_range[j])
    qpos[arm_qpos_indices(model, joints)] = home_q
    ctrl = np.zeros(model.nu + added)
    ctrl[list(servo_ids)] = home_q
    spec.add_key(name=HOME_KEY, qpos=qpos.tolist(), ctrl=ctrl.tolist())


def _one_line(err: Exception) -> str:
    return " ".join(str(err).split())
