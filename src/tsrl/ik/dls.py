"""Damped least-squares IK over task maps: one solver, `DlsSolver`, with `.step` for control loops
and `.solve` for the robust full solve (options and result in `options.py`).

The maths and the benchmark behind the defaults are in docs/ik.md.
"""

from __future__ import annotations

import math
from functools import partial

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..exceptions import InvalidConfig
from ..kinematics import Joints, as_slice, joint_ids, joint_limits
from ..taskmaps.base import TaskMap, TaskMapValue
from ..taskmaps.stack import Stack
from .options import IKOptions, IKResult, _finite, _vector

#: An attempt has stalled when its error is above STALL_RATIO times the error STALL_WINDOW
#: iterations earlier; it then gives way to a restart (while restarts are left).
STALL_WINDOW = 8
STALL_RATIO = 0.5

_HINGE = int(mujoco.mjtJoint.mjJNT_HINGE)
_MIN_PIVOT = 1e-300  # keeps mju_cholFactor away from sqrt(negative) in round-off; damping > 0 does the rest


class _Workspace:
    """Buffers of `_dls` for an (m, m) system: A, its diagonal (a view) and x (m,)."""

    def __init__(self, m: int):
        self.A = np.empty((m, m))
        self.diag = self.A.reshape(-1)[:: m + 1]
        self.x = np.empty(m)

    def __reduce__(self) -> tuple:
        return (_Workspace, (self.x.size,))  # a fresh one: pickle would cut diag off from A


def _dls(J: np.ndarray, e: np.ndarray, damping: float, d: np.ndarray | None, ws: _Workspace) -> np.ndarray:
    r"""Damped least squares dq = J^T (J J^T + \lambda I)^{-1} e (+ null-space term), J (k, n) and e (k,)
    C-contiguous float64, in a workspace for m = min(k, n).

    With d (n,): dq = d + J^T (J J^T + lambda I)^{-1} (e - J d) = J^+ e + (I - J^+ J) d, J^+ the damped
    pseudo-inverse. Solved by Cholesky in the smaller of the task (k x k) and joint (n x n) spaces,
    which give the same dq.
    """
    k, n = J.shape
    if d is not None:
        e = e - J @ d
    A, x = ws.A, ws.x
    dq = np.empty(n)
    if k <= n:  # task space: (J J^T + lambda I) x = e, dq = J^T x
        mujoco.mju_mulMatMatT(A, J, J)
        ws.diag += damping
        mujoco.mju_cholFactor(A, _MIN_PIVOT)
        mujoco.mju_cholSolve(x, A, e)
        mujoco.mju_mulMatTVec(dq, J, x)
    else:  # joint space: (J^T J + lambda I) dq = J^T e
        mujoco.mju_mulMatTMat(A, J, J)
        ws.diag += damping
        mujoco.mju_cholFactor(A, _MIN_PIVOT)
        mujoco.mju_mulMatTVec(x, J, e)
        mujoco.mju_cholSolve(dq, A, x)
    if d is not None:
        dq += d
    return dq


def _float_difference(task_map: TaskMap, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """task_map.difference(a, b) as a C-contiguous float64 array (a map of the caller's may return any)."""
    return np.ascontiguousarray(task_map.difference(a, b), dtype=np.float64)


class DlsSolver:
    r"""Damped least-squares IK of one task map over the controlled joints of a model.

    Each step, at q: e = W (y* - y) with y* - y from `task_map.difference`, J_W = W J[:, joints' dofs],
    lambda = damping + adaptive_damping ||e||^2 and

    .. math:: \Delta q = d + J_W^T (J_W J_W^T + \lambda I)^{-1} (e - J_W d),
              \quad d = k\,(q_{rest} - q)

    (d = 0 without a posture), ||dq|| <= max_step. A joint that q + dq would take out of its range is
    held at the limit and the step solved again for the others; q + dq is finally clipped to the
    limits. On an arm with more joints than task rows, d moves the arm toward the rest posture in the
    (damped) null space of the task: the TCP stays where the task puts it (docs/ik.md).

    Args:
        model: the MuJoCo model the task map was built for.
        task_map: the map phi (dim rows); a `Stack` for several maps.
        joints: names of the hinge or slide joints to move, in order; None for every hinge and slide
            joint of the model (the six arm joints in the UR5e scenes; see `tsrl.kinematics.joint_ids`).
        options: `IKOptions`; None for the defaults.

    Raises:
        InvalidConfig: weights, posture or posture gain of the wrong size; a joint that is not a hinge
            or slide joint.
        UnknownName: a joint name the model does not have.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        task_map: TaskMap,
        joints: Joints = None,
        options: IKOptions | None = None,
    ):
        self.model, self.task_map = model, task_map
        self.options = options = IKOptions() if options is None else options
        ids = joint_ids(model, joints)
        #: Names of the moved joints, in the order of q.
        self.joints: tuple[str, ...] = tuple(model.joint(j).name for j in ids)
        n = len(ids)
        #: qpos entries of the joints: a slice where they are contiguous (faster to read and write).
        self.qpos_indices = as_slice([model.jnt_qposadr[j] for j in ids])
        dadr = np.array([model.jnt_dofadr[j] for j in ids])
        # Columns of J to keep; None where the joints' dofs are all of J's columns, in order.
        self._dofs = None if np.array_equal(dadr, np.arange(model.nv)) else dadr
        limits = joint_limits(model, self.joints)
        self.lower, self.upper = limits[:, 0].copy(), limits[:, 1].copy()
        # Restart seeds: hinges within [-pi, pi] (every angle once), slides within their range
        # (at 0 for a slide without limits).
        hinge = np.array([int(model.jnt_type[j]) == _HINGE for j in ids])
        limited = np.isfinite(limits[:, 0])
        self._seed_lo = np.where(hinge, np.maximum(self.lower, -np.pi), np.where(limited, self.lower, 0.0))
        self._seed_hi = np.where(hinge, np.minimum(self.upper, np.pi), np.where(limited, self.upper, 0.0))
        self._workspace = _Workspace(min(n, task_map.dim))
        if isinstance(task_map, Stack):  # its own difference is fast for one value
            self._difference = task_map.difference
        else:
            self._difference = partial(_float_difference, task_map)
        self._weights = self._weight_rows = None
        if options.weights is not None:
            self._weights = _vector("weights", options.weights, task_map.dim, "(one per row of the task map)")
            self._weight_rows = self._weights[:, None]
        self._posture = None
        if options.posture is not None:
            self._posture = _vector("posture", options.posture, n, "(one per moved joint)")
        self._gain: float | np.ndarray = options.posture_gain  # type: ignore[assignment]
        if not isinstance(self._gain, float):
            self._gain = _vector("posture_gain", self._gain, n, "(one per moved joint) or one number")

    # -- control loops -----------------------------------------------------------------------------
    def step(self, q: np.ndarray, value: TaskMapValue, target: np.ndarray) -> tuple[np.ndarray, float]:
        """One damped least-squares step from the joints' positions q (n,), the map's value (y, J) at q
        and the target y* (dim,); the paper's q* = q + J^T (J J^T + eps I)^-1 (y* - y) with the
        options' damping, weights, posture term and step bound.

        For control loops, which evaluate the map once per period and hand its value over: nothing
        is evaluated and nothing is checked (float64 arrays of the right shapes, finite, J
        C-contiguous, as the map's own value is; the environments build them from the same map). q
        and value are not written. The step is taken from q even outside the limits; only q_next is
        clipped. A step that is not finite gives clip(q).

        Returns:
            q_next: q + dq within the joint limits (n,).
            residual: ||W (y* - y) - W J (q_next - q)||, the error the linearised map predicts at q_next.
        """
        e, J, err = self._residual(value, target)
        q_next = self._next(q, e, J, err)
        if q_next is None:
            q_next = self._clip(q.copy())
        r = e - J.dot(q_next - q)
        return q_next, math.sqrt(r.dot(r))

    # -- the full solve ----------------------------------------------------------------------------
    def solve(
        self, data: mujoco.MjData, target: ArrayLike, initial_value: TaskMapValue | None = None
    ) -> IKResult:
        """Joint positions that bring the map to `target` (dim,), from the configuration in `data`.

        Steps until ||W e|| < tol. An attempt that stalls (error above STALL_RATIO times its value
        STALL_WINDOW iterations earlier) gives way to a restart from a random configuration within
        the limits, up to `restarts` times. Never raises on non-convergence and never returns NaN.

        `data` is the workspace: on return its qpos holds the returned q at the moved joints (other
        coordinates, such as a free object's, are never written) and its kinematics (mj_kinematics +
        mj_comPos) are up to date. Pass a scratch MjData where the physics state must stay untouched.
        `initial_value`, the map's value at the start configuration when the caller has it, skips
        the first evaluation (and `data` is not touched if the start already meets tol).

        Returns:
            IKResult: the first converged iterate; if no attempt converges, the lowest-error iterate
            of the first attempt (the local least-squares compromise, not a far-away restart).

        Raises:
            InvalidConfig: a target of the wrong shape or with NaN/inf, an initial value of the wrong
                shape, non-finite joint positions in `data`.
        """
        opts = self.options
        target = _vector("target", target, self.task_map.dim, "for the task map's rows")
        q = data.qpos[self.qpos_indices].copy()
        if not _finite(q):
            raise InvalidConfig(f"data.qpos holds non-finite joint positions {q!r}")
        if initial_value is not None and (q == self._clip(q.copy())).all():  # used only within limits
            e, J, err = self._residual(self._checked(initial_value), target)
            evaluated = None  # data not touched yet
        else:
            q = self._clip(q)
            e, J, err = self._evaluate(data, q, target)
            evaluated = q  # the configuration whose kinematics data holds
        history = [err]
        best_q, best_err = q, err  # over the first attempt, until one converges
        seeds: np.random.Generator | None = None
        for attempt in range(opts.restarts + 1):
            if attempt > 0:
                if seeds is None:
                    seeds = np.random.default_rng(opts.seed)
                q = seeds.uniform(self._seed_lo, self._seed_hi)
                e, J, err = self._evaluate(data, q, target)
                evaluated = q
                history.append(err)
            first = len(history) - 1
            for _ in range(opts.max_iters):
                if err < opts.tol:
                    break
                if (
                    attempt < opts.restarts
                    and len(history) - first > STALL_WINDOW
                    and not err <= STALL_RATIO * history[-1 - STALL_WINDOW]
                ):
                    break
                q_next = self._next(q, e, J, err)
                if q_next is None:
                    break
                q = evaluated = q_next
                e, J, err = self._evaluate(data, q, target)
                history.append(err)
                if attempt == 0 and err < best_err:
                    best_q, best_err = q, err
            if err < opts.tol:
                best_q, best_err = q, err
                break
        if evaluated is not None and best_q is not evaluated:
            self._evaluate(data, best_q, target)
        return IKResult(best_q.copy(), best_err, len(history) - 1, best_err < opts.tol, tuple(history))

    # -- internals ---------------------------------------------------------------------------------
    def _checked(self, value: TaskMapValue) -> TaskMapValue:
        """A caller's (y, J) as float64 arrays, J C-contiguous; raises InvalidConfig on wrong shapes."""
        y, J = value
        dim, nv = self.task_map.dim, self.model.nv
        if np.shape(y) != (dim,) or np.shape(J) != (dim, nv):
            raise InvalidConfig(
                f"initial_value has y {np.shape(y)} and J {np.shape(J)}; expected ({dim},) and ({dim}, {nv})"
            )
        return TaskMapValue(np.asarray(y, dtype=np.float64), np.ascontiguousarray(J, dtype=np.float64))

    def _evaluate(
        self, data: mujoco.MjData, q: np.ndarray, target: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """Sets the joints to q in data, runs mj_kinematics + mj_comPos, returns (e, W J, ||e||)."""
        model = self.model
        data.qpos[self.qpos_indices] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        y, J = self.task_map(model, data)
        return self._residual(TaskMapValue(y, np.ascontiguousarray(J, dtype=np.float64)), target)

    def _residual(self, value: TaskMapValue, target: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(e (k,), W J (k, n), ||e||) for a value (y, J) of float64 arrays, J C-contiguous."""
        y, J = value
        e = self._difference(target, y)
        if self._dofs is not None:
            J = np.ascontiguousarray(J[:, self._dofs])  # fancy indexing may give F order
        if self._weights is not None:
            e = e * self._weights
            J = J * self._weight_rows
        err = math.sqrt(e.dot(e))
        return e, J, err if math.isfinite(err) else math.inf  # a NaN in y never reaches the result

    def _next(self, q: np.ndarray, e: np.ndarray, J: np.ndarray, err: float) -> np.ndarray | None:
        """q + dq, ||dq|| <= max_step, clipped to the limits; None if dq is not finite."""
        opts = self.options
        lam = opts.damping + opts.adaptive_damping * err * err
        d = None if self._posture is None else self._gain * (self._posture - q)
        dq = _dls(J, e, lam, d, self._workspace)
        norm = math.sqrt(dq.dot(dq))
        if not math.isfinite(norm):
            return None
        if norm > opts.max_step:
            dq *= opts.max_step / norm
        dq += q
        unclipped = dq.tobytes()
        q_next = self._clip(dq)
        if q_next.tobytes() != unclipped:  # a joint would leave its range: hold it, move the others
            return self._clamped(q, q_next, e, J, lam, d, np.frombuffer(unclipped))
        return q_next

    def _clamped(
        self,
        q: np.ndarray,
        q_next: np.ndarray,
        e: np.ndarray,
        J: np.ndarray,
        lam: float,
        d: np.ndarray | None,
        unclipped: np.ndarray,
    ) -> np.ndarray:
        """The step with the joints that leave their range held at the limit they cross and the task
        (and posture) met by the others: dq_free = DLS(J_free, e - J_held dq_held); repeated while
        another joint leaves its range. q + dq, ||dq|| <= max_step, within the limits."""
        free = q_next == unclipped
        for _ in range(free.size):
            if not free.any():
                break
            held = ~free
            dq = q_next - q  # held joints: to their limit
            e_free = e - J[:, held] @ dq[held]
            J_free = np.ascontiguousarray(J[:, free])
            d_free = None if d is None else d[free]
            dq[free] = _dls(J_free, e_free, lam, d_free, _Workspace(min(J_free.shape)))
            norm = math.sqrt(dq.dot(dq))
            if norm > self.options.max_step:
                dq *= self.options.max_step / norm
            unclipped = q + dq
            q_next = self._clip(unclipped.copy())
            leaving = q_next != unclipped
            if not leaving.any():
                break
            free &= ~leaving
        return q_next

    def _clip(self, q: np.ndarray) -> np.ndarray:
        """q clipped to the joint limits, in place."""
        return np.minimum(np.maximum(q, self.lower, out=q), self.upper, out=q)

    def __repr__(self) -> str:
        return f"<DlsSolver {self.task_map.spec} over {', '.join(self.joints)}>"
