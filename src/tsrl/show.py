"""A scene (built in, or an MJCF file) rendered at its home pose and at seeded random poses, to PNG files."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

from .assets import SCENES, load_model
from .kinematics import arm_qpos_indices, forward_kinematics, joint_limits, name_to_id

#: Random poses are home + U(-POSE_SPREAD, POSE_SPREAD) per joint [rad or m], so the arm stays in view.
POSE_SPREAD = 0.6


def render_poses(
    out_dir: Path, scene: str = "reach", n_random: int = 3, seed: int = 0, camera: str | None = None
) -> list[Path]:
    """Renders `scene` at its home keyframe (else qpos0) and at `n_random` seeded random poses near it
    into `out_dir` as <scene or model file stem>_home.png, ..._random_<i>.png, seen from `camera` (a
    camera of the model; None: tsrl.rendering.default_camera); returns the PNG paths. An unknown camera
    raises UnknownName listing the model's cameras, before anything is written."""
    from PIL import Image

    from .rendering import SceneRenderer

    model = load_model(scene)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    qpos = arm_qpos_indices(model)  # the arm's joints (every hinge and slide joint)
    home = model.key_qpos[name_to_id(model, "key", "home")][qpos] if model.nkey else model.qpos0[qpos]
    limits = joint_limits(model)
    poses = [("home", home)] + [
        (f"random_{i}", np.clip(home + rng.uniform(-POSE_SPREAD, POSE_SPREAD, len(home)), *limits.T))
        for i in range(n_random)
    ]
    stem = scene if scene in SCENES else Path(scene).stem  # a model file's name, not its path
    paths = []
    with SceneRenderer(model, camera=camera) as renderer:
        out_dir.mkdir(parents=True, exist_ok=True)
        for name, q in poses:
            forward_kinematics(model, data, q)
            mujoco.mj_camlight(model, data)  # the model's cameras and lights where the pose puts them
            path = out_dir / f"{stem}_{name}.png"
            Image.fromarray(renderer.render(data)).save(path)
            paths.append(path)
    return paths
