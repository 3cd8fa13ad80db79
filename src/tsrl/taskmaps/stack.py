"""Stack: the multi-task map, values concatenated and Jacobians stacked, with named slices."""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from ..exceptions import SpecError
from .base import TaskMap
from .frames import Frame, FrameCache
from .orientation import Quaternion
from .velocity import Velocity

_F64 = np.dtype(np.float64)


class _Views(NamedTuple):
    """Views into the output buffers y (dim,) and J (dim, nv) of a `Stack`'s last call, by part."""

    y: np.ndarray  # the buffers sliced
    J: np.ndarray
    own: list[tuple[TaskMap, np.ndarray, np.ndarray]]
    """Parts evaluated on their own: (part, y rows, J rows)."""
    velocities: list[tuple[Velocity, np.ndarray, np.ndarray, np.ndarray]]
    """Velocity parts whose inner map is an earlier part: (part, the inner map's J rows, y rows, J rows)."""
    repeated: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]
    """Repeated parts, copied from their first occurrence: (y rows, J rows, first y rows, first J rows)."""


class Stack(TaskMap):
    """Parts' values concatenated (dim = sum of parts) and Jacobians stacked (dim, nv).

    Nested stacks are flattened. `slices[part.spec]` is the part's rows, e.g.
    `stack.slices["position(tcp)"]`; a part that appears again is keyed "position(tcp)#2", and so
    on, so the slices always tile 0..dim in order. One frame cache serves all parts, so each
    frame's pose and Jacobian is computed once per call.
    """

    parts: tuple[TaskMap, ...]
    """The parts in order, nested stacks flattened."""
    _views: _Views | None = None  # sliced once per output buffer pair (y, J)

    def __init__(self, parts: Iterable[TaskMap]):
        flat: list[TaskMap] = []
        for p in parts:
            flat.extend(p.parts if isinstance(p, Stack) else [p])
        if not flat:
            raise SpecError("a stack needs at least one task map")
        self.parts = tuple(flat)
        self.slices: dict[str, slice] = {}
        start = 0
        for p in self.parts:
            key, n = p.spec, 1
            while key in self.slices:  # a repeated part is keyed "position(tcp)#2", "#3", ...
                n += 1
                key = f"{p.spec}#{n}"
            self.slices[key] = slice(start, start + p.dim)
            start += p.dim
        self.dim = start
        self.spec = ", ".join(p.spec for p in self.parts)
        self._spans = tuple(self.slices.values())
        # A part repeated (same spec) is evaluated once and copied: index of each part's first occurrence.
        first: dict[str, int] = {}
        self._first = tuple(first.setdefault(p.spec, i) for i, p in enumerate(self.parts))
        # Only parts whose coordinates can jump (quaternions) need their own difference.
        self._jumpy = tuple(
            (p, span)
            for p, span in zip(self.parts, self._spans)
            if type(p).difference is not TaskMap.difference
        )
        # The same for one value (1-D a and b): None stands for a `Quaternion` part, whose rule
        # a - sign(a . b) b is applied inline (numpy's general path costs as much as evaluating the map).
        self._jumpy_1d = tuple(
            (None if type(p).difference is Quaternion.difference else p, span) for p, span in self._jumpy
        )

    def frame_refs(self) -> tuple[Frame, ...]:
        return tuple(f for p in self.parts for f in p.frame_refs())

    @property
    def frames(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(f for p in self.parts for f in p.frames))

    def evaluate(self, cache: FrameCache, y: np.ndarray, J: np.ndarray) -> None:
        views = self._views
        if views is None or views.y is not y or views.J is not J:  # slice once per output buffer
            views = self._views = self._slice(y, J)
        for part, y_part, J_part in views.own:
            part.evaluate(cache, y_part, J_part)
        for velocity, J_map, y_part, J_part in views.velocities:
            velocity.evaluate_from(J_map, cache, y_part, J_part)
        for y_part, J_part, y_first, J_first in views.repeated:
            y_part[:] = y_first
            J_part[:] = J_first

    def _slice(self, y: np.ndarray, J: np.ndarray) -> _Views:
        rows = [(y[s], J[s]) for s in self._spans]
        first_rows = {p.spec: rows[i] for i, p in enumerate(self.parts) if self._first[i] == i}
        views = _Views(y, J, [], [], [])
        for i, p in enumerate(self.parts):
            if self._first[i] != i:
                continue
            if isinstance(p, Velocity) and p.map.spec in first_rows:
                # the inner map is evaluated on its own (a velocity map never is an inner map), first
                views.velocities.append((p, first_rows[p.map.spec][1], *rows[i]))
            else:
                views.own.append((p, *rows[i]))
        views.repeated.extend((*rows[i], *rows[f]) for i, f in enumerate(self._first) if f != i)
        return views

    def difference(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """a - b, each part's rows by the part's own `difference`; a, b (dim,) or (B, dim).

        Only parts that override `difference` (quaternions) are treated on their own rows; for one
        value (the IK's case, once per iteration) a quaternion's rule is applied inline.
        """
        if type(a) is not np.ndarray or a.dtype is not _F64:  # asarray costs more than these checks
            a = np.asarray(a, dtype=np.float64)
        if type(b) is not np.ndarray or b.dtype is not _F64:
            b = np.asarray(b, dtype=np.float64)
        out = a - b
        if not self._jumpy:
            return out
        if out.ndim == 1 and a.ndim == 1:
            for part, span in self._jumpy_1d:
                if part is None:  # a quaternion: a - sign(a . b) b, sign 1 at 0
                    if a[span].dot(b[span]) < 0.0:
                        out[span] = a[span] + b[span]
                else:
                    out[span] = part.difference(a[span], b[span])
            return out
        for part, span in self._jumpy:
            out[..., span] = part.difference(a[..., span], b[..., span])
        return out

    def __len__(self) -> int:
        return len(self.parts)
