"""Plain standard-DH and modified (Craig) DH forward kinematics in numpy: the independent references
for MuJoCo's frames."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike


def dh_transform(a: float, d: float, alpha: float, theta: float) -> np.ndarray:
    """Standard DH link transform T_{i-1,i} = Rz(theta) Tz(d) Tx(a) Rx(alpha), shape (4, 4)."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_forward(dh_table: Sequence[tuple[float, float, float]], q: ArrayLike) -> np.ndarray:
    """Pose T_0n of the last DH frame in the base frame, shape (4, 4).

    Args:
        dh_table: rows (a, d, alpha) in metres and radians, one per joint.
        q: joint angles (n,) in radians, added to each row's theta = 0.
    """
    return _chain(dh_transform, dh_table, q)


def modified_dh_transform(a: float, d: float, alpha: float, theta: float) -> np.ndarray:
    """Modified (Craig) DH link transform T_{i-1,i} = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i), (4, 4).

    `a` and `alpha` are those of the previous link (a_{i-1}, alpha_{i-1}), as a modified DH table
    lists them on row i (Franka's documentation does).
    """
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def modified_dh_forward(mdh_table: Sequence[tuple[float, float, float]], q: ArrayLike) -> np.ndarray:
    """Pose T_0n of the last modified-DH frame in the base frame, shape (4, 4).

    Args:
        mdh_table: rows (a_{i-1}, d_i, alpha_{i-1}) in metres and radians, one per joint.
        q: joint angles (n,) in radians, added to each row's theta = 0.
    """
    return _chain(modified_dh_transform, mdh_table, q)


def _chain(
    link: Callable[[float, float, float, float], np.ndarray],
    table: Sequence[tuple[float, float, float]],
    q: ArrayLike,
) -> np.ndarray:
    """The product of `link(a, d, alpha, theta)` over the rows of `table` with theta = q, shape (4, 4)."""
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (len(table),):
        raise ValueError(f"q has shape {q.shape}; expected ({len(table)},) for this DH table")
    T = np.eye(4)
    for (a, d, alpha), theta in zip(table, q):
        T = T @ link(a, d, alpha, theta)
    return T
