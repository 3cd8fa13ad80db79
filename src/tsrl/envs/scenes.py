"""A task's MuJoCo model: a built-in scene, or a model file (MJCF or URDF) with the task's robot made
ready on it (tsrl.robot_model: servos, gravity compensation, pins, home) and the goal marker added."""

from __future__ import annotations

from pathlib import Path

import mujoco

from ..assets import SCENES, load_model, scene_path
from ..exceptions import InvalidConfig, ModelLoadError
from ..model_files import resolve_model_path
from ..robot_model import compile_spec, prepare_spec, robot_label
from ..robots import ROBOTS, load_robot
from .task_frames import add_frame_aliases, express_in_base
from .tasks import Task

#: The goal marker every task's scene has (or gets): a mocap body and its site, the frame of the desired goal.
TARGET_BODY = "target"
TARGET_SITE = "target"
#: Model files a task's `scene` may name by path.
MODEL_SUFFIXES = (".xml", ".urdf")


def load_scene(task: Task) -> mujoco.MjModel:
    """Compiles the task's scene.

    A built-in scene with a built-in robot is compiled as it is (those arms have their own servos and
    the frames `tcp` and `base`). Otherwise the scene's MjSpec gets the robot prepared
    (`tsrl.robot_model.prepare_spec`), the sites `tcp` and `base` where it lacks them
    (envs/task_frames.py) and, with frame = "base", the scene expressed in the base frame, before it
    is compiled. A file path is relative to the task file, or names a file inside an installed package
    (`pkg://<package>/<path>`, tsrl.model_files); a model without a `target` body gets one (a mocap
    body with a `target` site, no collisions), placed at the goal box centre.

    Raises:
        InvalidConfig: no such scene or file; a robot file whose names or settings do not fit the
            model (one line naming the robot file and the key).
        ModelLoadError: MuJoCo cannot load the file.
    """
    if task.scene in SCENES and task.robot in ROBOTS and task.frame == "world":
        return load_model(task.scene)
    in_file = f"{task.source}: " if task.source is not None else ""
    path = _scene_file(task, in_file)
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as err:
        reason = " ".join(str(err).split())
        raise ModelLoadError(f"{in_file}scene = {str(path)!r}: MuJoCo could not load it: {reason}") from None
    robot = load_robot(task.robot_path)
    label = robot_label(task.robot_path)
    prepare_spec(spec, robot, label)
    add_frame_aliases(spec, compile_spec(spec, label), robot, label)
    if task.frame == "base":
        express_in_base(spec, f"{task.source or task.name}")
    if spec.body(TARGET_BODY) is None:
        body = spec.worldbody.add_body(name=TARGET_BODY, mocap=True, pos=list(task.goal.position.center))
        body.add_site(
            name=TARGET_SITE,
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[0.015, 0, 0],
            rgba=[0.9, 0.1, 0.1, 0.8],
        )
    return compile_spec(spec, f"{in_file}scene = {str(path)!r}")


def _scene_file(task: Task, in_file: str) -> Path:
    """The scene's model file: a built-in scene's, a package's (`pkg://`), or a path (relative to the task file)."""
    if task.scene in SCENES:
        return scene_path(task.scene)
    base = task.source.parent if task.source is not None else None
    try:
        path = resolve_model_path(task.scene, base, key="scene")
    except InvalidConfig as err:
        raise InvalidConfig(f"{in_file}{err}") from None
    if path.suffix.lower() not in MODEL_SUFFIXES or not path.is_file():
        raise InvalidConfig(
            f"{in_file}scene = {task.scene!r}: neither a built-in scene ({', '.join(SCENES)}) nor an "
            f"existing model file ({', '.join(MODEL_SUFFIXES)})"
        )
    return path
