"""`tsrl robot check FILE`: a doctor for a robot file (docs/robots.md).

Loads the robot file and its model as a task would (tsrl.robot_model: servos added where the model has
none, gravity compensation, pins, home), lists the controlled joints with their limits, the servos
(found or added, with their gains), the TCP and the base, checks the settling target
(tsrl.settling), checks that every corner of a reach box (given, or the default around the TCP's
home) and its centre are reached by tsrl's IK from home, and writes PNGs of the robot at home and at
the box corners. Exit 0 when everything holds, 2 with one line per problem (on stderr) otherwise.
"""

from __future__ import annotations

import itertools
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import mujoco
import numpy as np
from tyro.conf import Positional, arg

from .exceptions import InvalidConfig
from .ik import DlsSolver, IKOptions
from .kinematics import arm_qpos_indices, forward_kinematics, joint_limits, name_to_id
from .robot_model import PreparedArm, RobotNotice, load_robot_model, robot_label
from .robots import Robot, load_robot, reset_to_key
from .settling import STEP, settle
from .taskmaps import Position, resolve_frame
from .taskspace_box import DEFAULT_HALF_EXTENT, home_key, taskspace_box, tcp_at_home


@dataclass(frozen=True)
class BoxReach:
    """The IK from home to the reach box's corners and centre.

    Attributes:
        points: (9, 3) the eight corners, then the centre [m, world].
        q: (9, n) the IK's joint positions for each; residual: (9,) its error [m]; converged: (9,).
    """

    points: np.ndarray
    q: np.ndarray
    residual: np.ndarray
    converged: np.ndarray


@dataclass(frozen=True)
class CheckReport:
    """What `check_robot` found: the lines to print, the problems (one line each), the PNGs written."""

    lines: tuple[str, ...]
    problems: tuple[str, ...]
    images: tuple[Path, ...]


def box_points(center: np.ndarray, half_extent: np.ndarray) -> np.ndarray:
    """The eight corners (in binary order: -,-,- first) and the centre of a box, (9, 3)."""
    corners = [center + half_extent * np.array(s) for s in itertools.product((-1.0, 1.0), repeat=3)]
    return np.vstack([*corners, center])


def reach_box(
    model: mujoco.MjModel, robot: Robot, home: np.ndarray, key: int | None, points: np.ndarray
) -> BoxReach:
    """tsrl's IK (a local solve of position(tcp) from home, no restarts; the null-space posture at
    home on a redundant arm) to each point (k, 3)."""
    posture = tuple(float(q) for q in home) if len(robot.joints) > 6 else None
    options = IKOptions(max_iters=200, restarts=0, posture=posture)
    solver = DlsSolver(model, Position(model, robot.tcp), robot.joints, options)
    data = mujoco.MjData(model)
    qs, residuals, converged = [], [], []
    for point in points:
        _at_home(model, data, robot, home, key)
        result = solver.solve(data, point)
        qs.append(result.q)
        residuals.append(result.error_norm)
        converged.append(result.converged)
    return BoxReach(points, np.array(qs), np.array(residuals), np.array(converged))


def check_robot(
    file: str,
    box_center: tuple[float, float, float] | None = None,
    box_half_extent: tuple[float, float, float] | None = None,
    out_dir: Path | None = None,
    camera: str | None = None,
    size: tuple[int, int] = (480, 360),
) -> CheckReport:
    """Checks the robot file `file` (or a built-in robot's name); writes PNGs to `out_dir` (None: none).

    Raises:
        TsrlError: the robot file or its model cannot be loaded (one line naming the file and key).
    """
    robot = load_robot(file)
    where = robot_label(file)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RobotNotice)
        model, arm = load_robot_model(robot, where)
    named = f"robot {robot.name!r}"
    lines = [f"{named}{'' if where == named else f' ({where})'}: model {robot.model}"]
    lines += [f"notice: {w.message}" for w in caught if issubclass(w.category, RobotNotice)]
    lines += _joint_lines(model, robot)
    lines += _servo_lines(model, robot, arm)
    key = home_key(model, robot)
    home = robot.home_q(model)
    tcp_home = tcp_at_home(model, robot)
    lines.append(f"tcp: {robot.tcp} ({resolve_frame(model, robot.tcp).kind}), at home {_vec(tcp_home)} m")
    lines.append(f"base: {arm.base}")
    lines += [f"dropped: {d}" for d in arm.dropped]
    if robot.home is None:
        _check_zero_pose(model, robot, home, tcp_home, where)
    problems: list[str] = []

    settling = settle(model, robot.joints, robot.tcp, home, key, arm.servos)
    lines.append(f"settling: {settling.summary()}")
    for r in settling.responses:
        lines.append(
            f"  {r.direction}: {r.settled_error * 1e3:.3f} mm at 3 periods, at most {r.worst_after * 1e3:.3f} mm "
            f"after, overshoot {r.overshoot * 1e3:.2f} mm, {r.warnings} warnings"
        )
    if not settling.ok:
        problems.append(f"{where}: settling: {settling.summary()}")

    center = tcp_home if box_center is None else np.asarray(box_center, dtype=np.float64)
    half = np.full(3, DEFAULT_HALF_EXTENT) if box_half_extent is None else np.asarray(box_half_extent, float)
    if not (np.isfinite(center).all() and np.isfinite(half).all() and (half >= 0).all()):
        raise InvalidConfig(
            f"--box-center {center.tolist()}, --box-half-extent {half.tolist()}: finite, half >= 0"
        )
    box = reach_box(model, robot, home, key, box_points(center, half))
    reached = int(box.converged.sum())
    lines.append(
        f"reach box: centre {_vec(center)}, half-extent {_vec(half)} m: {reached}/{len(box.points)} "
        f"points (corners, centre) reached by the IK from home (largest residual {box.residual.max():.2g} m)"
    )
    low, high = taskspace_box(robot)
    source = "the robot's reach_low/reach_high" if robot.reach_low else "the default reach box around home"
    lines.append(
        f"taskspace box (action presets): {_vec(np.array(low))} .. {_vec(np.array(high))} m ({source})"
    )
    for point, residual, ok in zip(box.points, box.residual, box.converged, strict=True):
        if not ok:
            problems.append(
                f"{where}: reach box: {_vec(point)} not reached by the IK from home (residual {residual:.3g} m)"
            )

    images: list[Path] = []
    if out_dir is not None:
        images = _write_images(model, robot, home, key, box, tcp_home, out_dir, camera, size)
        lines.append(f"images: {len(images)} PNGs in {out_dir}")
    return CheckReport(tuple(lines), tuple(problems), tuple(images))


@dataclass(frozen=True)
class RobotCommand:
    """Check a robot file: joints, servos, TCP, base, the settling target, a reach box, pictures."""

    command: Positional[Literal["check"]]
    """check: the doctor (docs/robots.md)."""
    file: Positional[Annotated[str, arg(metavar="FILE")]]
    """A robot's .toml file, or a built-in robot's name (tsrl.robots.ROBOTS)."""
    box_center: tuple[float, float, float] | None = None
    """Centre [m] of the reach box to check (default: the TCP's home)."""
    box_half_extent: tuple[float, float, float] | None = None
    """Half-extent [m] of the reach box per axis (default: 0.15 on each)."""
    out_dir: Path | None = None
    """Where to write the PNGs (default: results/robot_check/<robot name>)."""
    images: bool = True
    """Write PNGs of the robot at home and at the box corners."""
    camera: str | None = None
    """A camera of the model to take the pictures with (default: one framing the box and the TCP)."""

    def run(self) -> int:
        robot = load_robot(self.file)
        out = (self.out_dir or Path("results/robot_check") / robot.name) if self.images else None
        report = check_robot(self.file, self.box_center, self.box_half_extent, out, self.camera)
        print("\n".join(report.lines))
        if report.problems:
            for problem in report.problems:
                print(f"tsrl robot check: {problem}", file=sys.stderr)
            return 2
        print("ok: every check holds")
        return 0


#: The `tsrl robot` command (cli.COMMANDS).
ROBOT_COMMANDS: dict[str, type] = {"robot": RobotCommand}


def _check_zero_pose(
    model: mujoco.MjModel, robot: Robot, zero: np.ndarray, tcp_zero: np.ndarray, where: str
) -> None:
    """A robot without `home` starts at the model's zero pose (qpos0). Raises InvalidConfig, naming the
    missing `home` as the likely cause, unless the IK moves the TCP settling.STEP (5 cm) from there
    along each world axis, both ways (the settling check's steps, none skipped)."""
    moves = STEP * np.vstack([np.eye(3), -np.eye(3)])
    moved = reach_box(model, robot, zero, None, tcp_zero + moves)
    if moved.converged.all():
        return
    failed = ", ".join(axis for axis, ok in zip(_AXES, moved.converged, strict=True) if not ok)
    raise InvalidConfig(
        f"{where}: no `home`, so the arm starts at the model's zero pose {_vec(zero)}, from which the IK "
        f"cannot move the TCP {STEP * 100:g} cm along {failed} (largest residual {moved.residual.max():.2g} m): "
        "likely a singular pose (a straight or folded arm); give `home`, a keyframe's name or one value "
        "per joint (e.g. the elbow bent)"
    )


_AXES = ("+x", "+y", "+z", "-x", "-y", "-z")


def _at_home(
    model: mujoco.MjModel, data: mujoco.MjData, robot: Robot, home: np.ndarray, key: int | None
) -> None:
    reset_to_key(model, data, key)
    data.qpos[arm_qpos_indices(model, robot.joints)] = home
    mujoco.mj_forward(model, data)


def _joint_lines(model: mujoco.MjModel, robot: Robot) -> list[str]:
    lines = [f"joints ({len(robot.joints)}, base to tip), range:"]
    width = max(len(j) for j in robot.joints)
    for joint, (lo, hi) in zip(robot.joints, joint_limits(model, robot.joints), strict=True):
        j = model.joint(joint).id
        kind, unit = (
            ("hinge", "rad") if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE) else ("slide", "m")
        )
        limits = f"[{lo:.4g}, {hi:.4g}] {unit}" if np.isfinite(lo) else "none (jointLimits refuses it)"
        lines.append(f"  {joint:<{width}}  {kind}  {limits}")
    return lines


def _servo_lines(model: mujoco.MjModel, robot: Robot, arm: PreparedArm) -> list[str]:
    if arm.added:
        head = (
            f"servos: added by tsrl, critically damped at {arm.bandwidth_hz:g} Hz (kp = m w^2, kv = 2 m w - "
            f"joint damping; m = M_ii at home), integrator implicitfast"
        )
    else:
        head = "servos: the model's own"
    head += ", gravity compensation added" if arm.gravity_compensation else ""
    lines = [head]
    width = max(len(s) for s in arm.servos)
    inertia = {g.joint: g.inertia for g in arm.added}
    for joint, servo in zip(robot.joints, arm.servos, strict=True):
        a = name_to_id(model, "actuator", servo)
        kp, kv = model.actuator_gainprm[a, 0], -model.actuator_biasprm[a, 2]
        lo, hi = model.actuator_ctrlrange[a] if model.actuator_ctrllimited[a] else (-np.inf, np.inf)
        m = f"m = {inertia[joint]:.4g}, " if joint in inertia else ""
        lines.append(
            f"  {model.actuator(a).name:<{width}}  {m}kp = {kp:.4g}, kv = {kv:.4g}, ctrl [{lo:.4g}, {hi:.4g}]"
        )
    return lines


def _write_images(
    model: mujoco.MjModel,
    robot: Robot,
    home: np.ndarray,
    key: int | None,
    box: BoxReach,
    tcp_home: np.ndarray,
    out_dir: Path,
    camera: str | None,
    size: tuple[int, int],
) -> list[Path]:
    from PIL import Image

    from .rendering import SceneRenderer, model_workspace, workspace_camera

    bodies, base = model_workspace(model)  # the robot, and the box and the TCP's home beside it
    view = camera or workspace_camera(model, np.vstack([bodies, box.points, tcp_home]), base)
    colours = np.tile([0.1, 0.4, 0.9, 0.9], (len(box.points), 1))
    data = mujoco.MjData(model)
    out_dir.mkdir(parents=True, exist_ok=True)
    poses = [("home", home)] + [(f"corner_{i}", q) for i, q in enumerate(box.q[:8])]
    paths = []
    with SceneRenderer(model, *size, camera=view) as renderer:
        for i, (name, q) in enumerate(poses):
            _at_home(model, data, robot, home, key)
            forward_kinematics(model, data, q, robot.joints)
            path = out_dir / f"{robot.name}_{name}.png"
            rgba = colours.copy()
            if i > 0:
                rgba[i - 1] = (0.9, 0.1, 0.1, 1.0)  # the corner the TCP is at
            Image.fromarray(renderer.render(data, markers=box.points, rgba=rgba)).save(path)
            paths.append(path)
    return paths


def _vec(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.3f}" for x in v) + "]"


__all__ = ("ROBOT_COMMANDS", "BoxReach", "CheckReport", "RobotCommand", "check_robot", "reach_box")
