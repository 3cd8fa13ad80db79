"""Off-screen rendering of a scene to RGB arrays (MUJOCO_GL=egl or osmesa, chosen before mujoco loads)."""

from __future__ import annotations

from typing import Self

import mujoco
import numpy as np

#: Default free camera: looking at the workspace in front of the robot (-x side), from the side.
DEFAULT_LOOKAT = (-0.35, -0.05, 0.25)
DEFAULT_DISTANCE = 1.9
DEFAULT_AZIMUTH = 135.0
DEFAULT_ELEVATION = -25.0


def default_camera() -> mujoco.MjvCamera:
    """A free camera framing the UR5e and its workspace."""
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = DEFAULT_LOOKAT
    cam.distance = DEFAULT_DISTANCE
    cam.azimuth = DEFAULT_AZIMUTH
    cam.elevation = DEFAULT_ELEVATION
    return cam


class SceneRenderer:
    """Renders (model, data) off-screen to RGB arrays (height, width, 3) uint8.

    Owns a GL context: call `close()` (or use it as a context manager) when done.
    """

    def __init__(self, model: mujoco.MjModel, width: int = 640, height: int = 480):
        self._renderer = mujoco.Renderer(model, height=height, width=width)
        self.camera = default_camera()

    def render(self, data: mujoco.MjData, camera: mujoco.MjvCamera | str | None = None) -> np.ndarray:
        """RGB image of the current state, shape (height, width, 3), dtype uint8."""
        self._renderer.update_scene(data, camera=self.camera if camera is None else camera)
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
