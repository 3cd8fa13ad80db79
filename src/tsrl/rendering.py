"""Off-screen rendering of a scene to RGB arrays (MUJOCO_GL=egl or osmesa, chosen before mujoco loads).

The camera finds the robot in any model: by default a free camera frames the workspace, the bodies
the model's joints move (the arm, objects) and its mocap bodies (the goal marker) at home;
`workspace_camera` frames given points (a task's goal box and the TCP's home); a camera of the model
itself is chosen by name.
"""

from __future__ import annotations

import math
from typing import Self

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from .exceptions import UnknownName
from .kinematics import names
from .taskmaps.frames import body_moves

#: The view: from 25 degrees above, 45 degrees off the line from the robot's base to the workspace.
ELEVATION = -25.0
AZIMUTH_OFFSET = -45.0
#: Margin around the framed points (1 = the bounding sphere touches the image's edges).
MARGIN = 1.3
#: Smallest framed radius [m]: a single point is seen from a sensible distance.
MIN_RADIUS = 0.3
#: Markers `SceneRenderer.render` draws: radius [m] and default colour.
MARKER_RADIUS = 0.012
MARKER_RGBA = (0.1, 0.4, 0.9, 0.9)


def workspace_camera(
    model: mujoco.MjModel, points: ArrayLike, base: ArrayLike | None = None
) -> mujoco.MjvCamera:
    """A free camera that frames `points` (k, 3) [m, world]: it looks at the centre of their bounding
    box from ELEVATION degrees above, AZIMUTH_OFFSET degrees off the horizontal line from `base` (3,)
    (where the robot stands) to that centre, at the distance where the box's bounding sphere fits the
    model's field of view with MARGIN to spare."""
    p = np.atleast_2d(np.asarray(points, dtype=np.float64))
    low, high = p.min(axis=0), p.max(axis=0)
    center = 0.5 * (low + high)
    radius = max(0.5 * float(np.linalg.norm(high - low)), MIN_RADIUS)
    heading = 0.0
    if base is not None:
        dx, dy = center[:2] - np.asarray(base, dtype=np.float64)[:2]
        if math.hypot(dx, dy) > 1e-6:
            heading = math.degrees(math.atan2(dy, dx))
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = center
    cam.distance = MARGIN * radius / math.sin(math.radians(model.vis.global_.fovy) / 2)
    cam.azimuth = heading + AZIMUTH_OFFSET
    cam.elevation = ELEVATION
    return cam


def model_workspace(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray | None]:
    """What the default camera frames: the positions (k, 3) of every body a joint moves and of every
    mocap body, at the model's home (its keyframe `home`, else its first keyframe, else qpos0), and the
    base: the position of the first hinge or slide joint's body (None if the model has none)."""
    data = mujoco.MjData(model)
    keys = names(model, "key")
    if keys:
        mujoco.mj_resetDataKeyframe(model, data, keys.index("home") if "home" in keys else 0)
    mujoco.mj_kinematics(model, data)
    moved = [b for b in range(1, model.nbody) if body_moves(model, b) or model.body_mocapid[b] >= 0]
    points = data.xpos[moved] if moved else data.xpos[:1]
    arm = [j for j in range(model.njnt) if int(model.jnt_type[j]) in _ARM_JOINTS]
    base = data.xpos[model.jnt_bodyid[arm[0]]].copy() if arm else None
    return points.copy(), base


def named_camera(model: mujoco.MjModel, name: str) -> mujoco.MjvCamera:
    """The model's camera `name` (MJCF <camera>). Raises UnknownName listing the model's cameras."""
    cid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, name)
    if cid < 0:
        raise UnknownName(
            "camera", name, [model.camera(i).name for i in range(model.ncam) if model.camera(i).name]
        )
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FIXED
    cam.fixedcamid = cid
    return cam


def default_camera(model: mujoco.MjModel) -> mujoco.MjvCamera:
    """The free camera framing the model's workspace (`model_workspace`)."""
    return workspace_camera(model, *model_workspace(model))


class SceneRenderer:
    """Renders (model, data) off-screen to RGB arrays (height, width, 3) uint8.

    Args:
        camera: a camera (e.g. `workspace_camera`), the name of one of the model's cameras, or None:
            `default_camera(model)`.

    Owns a GL context: call `close()` (or use it as a context manager) when done.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        width: int = 640,
        height: int = 480,
        camera: mujoco.MjvCamera | str | None = None,
    ):
        if isinstance(camera, str):
            camera = named_camera(model, camera)
        self.camera = default_camera(model) if camera is None else camera
        self._renderer = mujoco.Renderer(model, height=height, width=width)

    def render(
        self,
        data: mujoco.MjData,
        camera: mujoco.MjvCamera | str | None = None,
        markers: ArrayLike | None = None,
        rgba: ArrayLike = MARKER_RGBA,
    ) -> np.ndarray:
        """RGB image of the current state, shape (height, width, 3), dtype uint8; `markers` (k, 3)
        [m, world] are drawn as small spheres of colour `rgba` (4,) or (k, 4) (not part of the model)."""
        self._renderer.update_scene(data, camera=self.camera if camera is None else camera)
        if markers is not None:
            points = np.atleast_2d(np.asarray(markers, dtype=np.float64))
            colours = np.broadcast_to(np.asarray(rgba, dtype=np.float32), (len(points), 4))
            scene = self._renderer.scene
            for point, colour in zip(points, colours, strict=True):
                if scene.ngeom >= scene.maxgeom:
                    break
                mujoco.mjv_initGeom(
                    scene.geoms[scene.ngeom],
                    int(mujoco.mjtGeom.mjGEOM_SPHERE),
                    np.array([MARKER_RADIUS, 0.0, 0.0]),
                    point,
                    np.eye(3).ravel(),
                    colour,
                )
                scene.ngeom += 1
        return self._renderer.render().copy()

    def close(self) -> None:
        self._renderer.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def render_rgb(model: mujoco.MjModel, data: mujoco.MjData, width: int = 640, height: int = 480) -> np.ndarray:
    """One RGB image (height, width, 3) uint8 of the current state; opens and closes a renderer."""
    with SceneRenderer(model, width, height) as renderer:
        return renderer.render(data)


_ARM_JOINTS = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
