"""IK options and results: `IKOptions` (validated once, when built) and `IKResult`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from ..exceptions import InvalidConfig, is_int


def _number(name: str, value: float, *, minimum: float = 0.0, strict: bool = True) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidConfig(f"{name} must be a number; got {value!r}") from None
    if not (v > minimum if strict else v >= minimum):  # also rejects NaN
        raise InvalidConfig(f"{name} must be {'>' if strict else '>='} {minimum:g}; got {value!r}")
    return v


def _count(name: str, value: int, minimum: int) -> int:
    if not (is_int(value) or isinstance(value, np.integer)) or value < minimum:
        raise InvalidConfig(f"{name} must be an integer >= {minimum}; got {value!r}")
    return int(value)


def _finite(v: np.ndarray) -> bool:
    """Whether every entry of the 1-D float array v is finite.

    v . v is finite exactly when every entry is, unless the sum overflows; only then is each entry
    checked. One dot product costs a third of `np.isfinite(v).all()` on the short vectors of a step.
    """
    return math.isfinite(v.dot(v)) or bool(np.isfinite(v).all())


def _vector(name: str, value: ArrayLike, size: int | None = None, what: str = "") -> np.ndarray:
    """value as a finite 1-D float array (of shape (size,) when given); `what` goes into the error."""
    v = np.asarray(value, dtype=np.float64)
    if v.ndim != 1 or (size is not None and v.shape != (size,)):
        expected = f"({size},) {what}" if size is not None else "a 1-D sequence"
        raise InvalidConfig(f"{name} has shape {v.shape}; expected {expected}")
    if not _finite(v):
        raise InvalidConfig(f"{name} must be finite; got {v!r}")
    return v


def _tuple(name: str, value: ArrayLike | None, non_negative: bool = False) -> tuple[float, ...] | None:
    if value is None:
        return None
    v = _vector(name, value)
    if non_negative and (v < 0.0).any():
        raise InvalidConfig(f"{name} must be >= 0; got {v!r}")
    return tuple(float(x) for x in v)


@dataclass(frozen=True)
class IKOptions:
    """Options of a `DlsSolver`, validated once when built (InvalidConfig names the bad value).

    Sizes that depend on the task map (weights) or the joints (posture, a per-joint posture gain)
    are checked when the solver is built.
    """

    tol: float = 1e-4
    """`solve` stops when ||W (y* - y)|| < tol (units of the map's rows)."""
    max_iters: int = 100
    """Iterations per attempt of `solve` (the start and each restart)."""
    restarts: int = 30
    """Restarts of `solve` from random seeds after an attempt stalls; 0 for a purely local solve."""
    seed: int = 0
    """Seed of the restart configurations (a solve is deterministic)."""
    damping: float = 1e-6
    """Damping floor lambda_0 > 0 of lambda = lambda_0 + lambda_e ||W e||^2 (the paper's eps)."""
    adaptive_damping: float = 1e-3
    """lambda_e >= 0, the error-proportional damping (Levenberg-Marquardt in the style of Sugihara 2011)."""
    max_step: float = 1.0
    """Largest ||dq||_2 per step [rad for hinges]."""
    weights: tuple[float, ...] | None = None
    """Per-row weights W (dim,) of the task map, >= 0 (0 drops a row); None: all ones."""
    posture: tuple[float, ...] | None = None
    """Rest configuration (n,) pursued in the null space of the task; None: no posture term."""
    posture_gain: float | tuple[float, ...] = 0.1
    """Gain k >= 0 of the posture step k (posture - q): one number, or one per joint (n,)."""

    def __post_init__(self) -> None:
        set_ = object.__setattr__  # frozen: normalise the fields once, here
        set_(self, "tol", _number("tol", self.tol))
        set_(self, "max_iters", _count("max_iters", self.max_iters, 1))
        set_(self, "restarts", _count("restarts", self.restarts, 0))
        set_(self, "seed", _count("seed", self.seed, 0))
        set_(self, "damping", _number("damping", self.damping))
        set_(self, "adaptive_damping", _number("adaptive_damping", self.adaptive_damping, strict=False))
        set_(self, "max_step", _number("max_step", self.max_step))
        set_(self, "weights", _tuple("weights", self.weights, non_negative=True))
        set_(self, "posture", _tuple("posture", self.posture))
        gain = self.posture_gain
        if isinstance(gain, tuple) or np.ndim(gain) != 0:  # one gain per joint
            set_(self, "posture_gain", _tuple("posture_gain", gain, non_negative=True))
        else:
            set_(self, "posture_gain", _number("posture_gain", gain, strict=False))


class IKResult(NamedTuple):
    """What `DlsSolver.solve` found, converged or not."""

    q: np.ndarray  # (n,) positions of the solver's joints, within their limits
    error_norm: float  # ||W (y* - y)|| at q, y* - y from task_map.difference, W = diag(weights)
    iterations: int  # steps taken over all attempts; a jump to a restart seed counts as one
    converged: bool  # error_norm < tol
    error_history: tuple[float, ...]  # error norm at the start and after each iteration (iterations + 1)
