"""The task-map abstraction: phi(q) -> (y, J), evaluated on (model, data) after forward kinematics."""

from __future__ import annotations

import abc
from typing import Any, NamedTuple

import mujoco
import numpy as np

from .frames import Frame, FrameCache


class TaskMapValue(NamedTuple):
    """A task map's value and Jacobian at one configuration."""

    y: np.ndarray  # (dim,)
    J: np.ndarray  # (dim, nv), world-aligned, dy/dq in the tangent space (qvel coordinates)


class TaskMap(abc.ABC):
    """A feature phi: q -> y in R^dim with Jacobian J = dy/dq in R^{dim x nv}.

    Evaluated on (model, data) after forward kinematics (`tsrl.forward_kinematics` or any MuJoCo
    call that runs `mj_kinematics` and `mj_comPos`); never steps the physics.

    Calling a map returns fresh arrays: a caller may keep the value of one call while making the
    next. Subclasses implement `evaluate`, which writes into buffers and reads frame poses and
    Jacobians from a `FrameCache` that computes each frame once per top-level call (a `Stack`
    shares one cache between all its parts). A map is bound to the model it was built for.
    """

    #: Number of rows of y and J.
    dim: int
    #: Canonical spec text, e.g. "positionDiff(tcp, target)"; `parse_spec(map.spec, model)` rebuilds it.
    spec: str

    _workspace: _Workspace | None = None

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> TaskMapValue:
        """Returns (y, J) at the configuration held in `data`, as fresh arrays."""
        y, J = self.in_place(model, data)
        return TaskMapValue(y.copy(), J.copy())

    def in_place(self, model: mujoco.MjModel, data: mujoco.MjData) -> TaskMapValue:
        """As calling the map, but returns the map's own output buffers, not copies.

        The same two arrays (y (dim,), J (dim, nv)) come back from every call for `model`, each call
        overwriting them: for a control loop that reads them before it evaluates the map again.
        """
        ws = self._workspace
        if ws is None or ws.model is not model:
            ws = self._workspace = _Workspace(model, self)
        ws.cache.update(data)
        self.evaluate(ws.cache, ws.y, ws.J)
        return ws.value

    @abc.abstractmethod
    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        """Writes y (dim,) and J (dim, nv) in place at the configuration held in `cache.data`."""

    def frame_refs(self) -> tuple[Frame, ...]:
        """The resolved frames whose pose and Jacobian `evaluate` reads from the cache."""
        return ()

    @property
    def frames(self) -> tuple[str, ...]:
        """Names of the frames the map reads, from its resolved frames (relabelling asks which maps read
        the goal frame)."""
        return tuple(dict.fromkeys(f.name for f in self.frame_refs()))

    def difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a - b in the map's coordinates; override where coordinates can jump."""
        return a - b

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.spec} dim={self.dim}>"

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.pop("_workspace", None)  # holds the model and data of the last call; rebuilt on demand
        state.pop("_views", None)  # a Stack's views into the workspace buffers
        return state


class _Workspace:
    """A top-level map's frame cache and output buffers for one model."""

    def __init__(self, model: mujoco.MjModel, task_map: TaskMap):
        self.model = model
        self.cache = FrameCache(model, task_map.frame_refs())
        self.y = np.zeros(task_map.dim)
        self.J = np.zeros((task_map.dim, model.nv))
        self.value = TaskMapValue(self.y, self.J)
