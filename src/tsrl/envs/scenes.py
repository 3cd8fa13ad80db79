"""A task's MuJoCo model: a built-in scene, or a model file (MJCF or URDF) that gets the goal marker added."""

from __future__ import annotations

from pathlib import Path

import mujoco

from ..assets import SCENES, load_model
from ..exceptions import InvalidConfig, ModelLoadError
from .tasks import Task

#: The goal marker every task's scene has (or gets): a mocap body and its site, the frame of the desired goal.
TARGET_BODY = "target"
TARGET_SITE = "target"
#: Model files a task's `scene` may name by path.
MODEL_SUFFIXES = (".xml", ".urdf")


def load_scene(task: Task) -> mujoco.MjModel:
    """Compiles the task's scene. A file path is relative to the task file; a model without a `target`
    body gets one (a mocap body with a `target` site, no collisions), placed at the goal box centre."""
    if task.scene in SCENES:
        return load_model(task.scene)
    path = Path(task.scene)
    if not path.is_absolute() and task.source is not None:
        path = task.source.parent / path
    in_file = f"{task.source}: " if task.source is not None else ""
    if path.suffix.lower() not in MODEL_SUFFIXES or not path.is_file():
        raise InvalidConfig(
            f"{in_file}scene = {task.scene!r}: neither a built-in scene ({', '.join(SCENES)}) nor an "
            f"existing model file ({', '.join(MODEL_SUFFIXES)})"
        )
    try:
        spec = mujoco.MjSpec.from_file(str(path))
        if spec.body(TARGET_BODY) is None:
            body = spec.worldbody.add_body(name=TARGET_BODY, mocap=True, pos=list(task.goal.position.center))
            body.add_site(
                name=TARGET_SITE,
                type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[0.015, 0, 0],
                rgba=[0.9, 0.1, 0.1, 0.8],
            )
        return spec.compile()
    except ValueError as err:
        reason = " ".join(str(err).split())
        raise ModelLoadError(f"{in_file}scene = {str(path)!r}: MuJoCo could not load it: {reason}") from None
