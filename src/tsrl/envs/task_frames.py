"""The frames every task's specs may name on any robot, and a scene expressed in the robot's base frame.

Presets and task files name the TCP `tcp` and the robot's base `base`. A model whose robot file names
another TCP frame gets a site `tcp` at it (same body, same pose); a model without a frame `base` gets
a site `base` at the robot's base body (`tsrl.robot_model.arm_base`); so does a model whose body
`base` is not the one the robot file's `base` key names (sites come first where maps resolve a name,
so `base` then reads the robot file's base). So `fs1`, `taskspace` and every built-in task's maps
work on any arm.

A task with `frame = "base"` is expressed in the robot's base frame: every top-level element of the
scene moves into one frame at the inverse of the base's world pose, so that the base stands at the
origin with its axes along the world's, and every position of the task file (goal box, objects,
workspace bounds) and every map value is relative to the base. The base must stand upright (its z
axis along the world's: a rotation about z keeps gravity where it is).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ..exceptions import InvalidConfig
from ..robot_model import arm_base
from ..robots import Robot
from ..taskmaps.frames import body_moves

#: The names presets and built-in tasks give the robot's TCP and base.
TCP, BASE = "tcp", "base"


def add_frame_aliases(spec: mujoco.MjSpec, probe: mujoco.MjModel, robot: Robot, where: str) -> None:
    """Adds the sites `tcp` and `base` where the model lacks them (`probe`: the spec compiled).

    Raises:
        InvalidConfig: the model has a frame `tcp` that is not the robot's TCP.
    """
    if robot.tcp != TCP:
        if _frame(probe, TCP) is not None:
            raise InvalidConfig(
                f"{where}: tcp = {robot.tcp!r}, but the model has another frame named {TCP!r}, which presets "
                f"read as the TCP; rename that frame, or give tcp = {TCP!r}"
            )
        sid = mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_SITE, robot.tcp)
        if sid >= 0:  # the TCP site's body and its pose there (compiled: any orientation form resolved)
            body, pos, quat = int(probe.site_bodyid[sid]), probe.site_pos[sid], probe.site_quat[sid]
        else:
            body, pos, quat = mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_BODY, robot.tcp), np.zeros(3), None
        _add_site(spec, probe, body, TCP, pos, quat)
    frame = _frame(probe, BASE)
    body = mujoco.mj_name2id(probe, mujoco.mjtObj.mjOBJ_BODY, arm_base(probe, robot))
    if frame is None or (robot.base is not None and frame[0] == "body" and frame[1] != body):
        _add_site(spec, probe, max(body, 0), BASE, np.zeros(3), None)  # shadows another body `base`
    elif robot.base is not None and frame[0] == "site" and int(probe.site_bodyid[frame[1]]) != body:
        other = probe.body(int(probe.site_bodyid[frame[1]])).name
        raise InvalidConfig(
            f"{where}: base = {robot.base!r}, but the model has a site named {BASE!r} on body {other!r}, "
            f"which presets read as the base; rename that site, or give base = {other!r}"
        )


def express_in_base(spec: mujoco.MjSpec, where: str) -> None:
    """Moves every top-level element of `spec` into one frame at the inverse of the pose of its frame
    `base` at the model's default state (module docstring).

    Raises:
        InvalidConfig: the base moves with a joint, or does not stand upright.
    """
    probe = spec.compile()
    kind, index = _frame(probe, BASE) or ("", -1)
    data = mujoco.MjData(probe)
    mujoco.mj_kinematics(probe, data)
    if kind == "site":
        body, pos, rot = int(probe.site_bodyid[index]), data.site_xpos[index], data.site_xmat[index]
    else:
        body, pos, rot = index, data.xpos[index], data.xmat[index]
    if body_moves(probe, body):
        raise InvalidConfig(
            f'{where}: frame = "base": the robot\'s base (body {probe.body(body).name!r}) moves with '
            "a joint; accepted: a fixed base (name it with the robot file's `base` key)"
        )
    R = rot.reshape(3, 3)
    if R[2, 2] < 1.0 - 1e-9:
        raise InvalidConfig(
            f'{where}: frame = "base": the robot\'s base is tilted (its z axis is {R[:, 2].round(4).tolist()}); '
            "accepted: a base standing upright, turned about z at most"
        )
    yaw = np.arctan2(R[1, 0], R[0, 0])
    inverse_quat = np.array([np.cos(-yaw / 2), 0.0, 0.0, np.sin(-yaw / 2)])
    c, s = np.cos(yaw), np.sin(yaw)
    inverse_pos = -np.array([c * pos[0] + s * pos[1], -s * pos[0] + c * pos[1], pos[2]])
    world = spec.worldbody
    elements = [*_bodies(world), *world.geoms, *world.sites, *world.lights, *world.cameras, *world.frames]
    frame = world.add_frame(pos=inverse_pos, quat=inverse_quat)
    for element in elements:
        if element.frame is None:  # an element inside a frame moves with it
            element.set_frame(frame)


def _bodies(world: mujoco.MjsBody) -> list[mujoco.MjsBody]:
    bodies = []
    body = world.first_body()
    while body is not None:
        bodies.append(body)
        body = world.next_body(body)
    return bodies


def _frame(model: mujoco.MjModel, name: str) -> tuple[str, int] | None:
    """("site", id) or ("body", id) of the frame `name` (sites first, as task maps resolve), or None."""
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid >= 0:
        return "site", sid
    bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    return ("body", bid) if bid >= 0 else None


def _add_site(
    spec: mujoco.MjSpec, probe: mujoco.MjModel, body: int, name: str, pos: np.ndarray, quat: np.ndarray | None
) -> None:
    parent = spec.worldbody if body == 0 else spec.body(probe.body(body).name)
    site = parent.add_site(name=name, pos=list(pos), size=[0.005, 0, 0], group=5)
    if quat is not None:
        site.quat = list(quat)
