"""Damped least-squares IK over task maps: `dls_step`, `ik_step` and `IKStepper` (one step), `solve_ik`.

The maths and the benchmark behind the defaults are in docs/ik.md.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from typing import NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from ..assets.ur5e import JOINT_NAMES
from ..exceptions import InvalidConfig
from ..kinematics import as_slice, name_to_id
from ..taskmaps.base import TaskMap, TaskMapValue
from ..taskmaps.orientation import Quaternion
from ..taskmaps.stack import Stack

#: Stop when ||W (y* - y)|| falls below this.
DEFAULT_TOL = 1e-4
#: Iterations per attempt (the start and each restart).
DEFAULT_MAX_ITERS = 100
#: Restarts from random seeds after an attempt stalls.
DEFAULT_RESTARTS = 30
#: Damping floor lambda_0 of lambda = lambda_0 + lambda_e ||e||^2.
DEFAULT_DAMPING = 1e-6
#: Error-proportional damping lambda_e (Levenberg-Marquardt in the style of Sugihara 2011).
DEFAULT_ADAPTIVE_DAMPING = 1e-3
#: Largest joint step ||dq||_2 per iteration [rad for hinges].
DEFAULT_MAX_STEP = 1.0
#: Gain k of the posture term dq_0 = k (q_posture - q), projected onto the null space of J.
DEFAULT_POSTURE_GAIN = 0.1

#: An attempt has stalled when its error is above STALL_RATIO times the error STALL_WINDOW
#: iterations earlier; it then gives way to a restart (while restarts are left).
STALL_WINDOW = 8
STALL_RATIO = 0.5

_HINGE, _SLIDE = int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE)
_MIN_PIVOT = 1e-300  # keeps mju_cholFactor away from sqrt(negative) in round-off; damping > 0 does the rest


class IKResult(NamedTuple):
    """What `solve_ik` found, converged or not."""

    q: np.ndarray  # (n,) positions of the moved joints (the six arm joints by default), within limits
    error_norm: float  # ||W (y* - y)|| at q, y* - y from task_map.difference, W = diag(weights)
    iterations: int  # steps taken over all attempts; a jump to a restart seed counts as one
    converged: bool  # error_norm < tol
    error_history: tuple[float, ...]  # error norm at the start and after each iteration (iterations + 1)


def dls_step(
    J: ArrayLike, error: ArrayLike, damping: float, nullspace: ArrayLike | None = None
) -> np.ndarray:
    r"""Damped least squares: dq = J^T (J J^T + damping I)^{-1} error (the paper's step, eps = damping).

    .. math:: \Delta q = J^T (J J^T + \lambda I)^{-1} e

    With `nullspace` d (n,), the step also moves along d inside the (damped) null space of J:
    dq = d + J^T (J J^T + damping I)^{-1} (error - J d), which is J^+ e + (I - J^+ J) d with the
    damped pseudo-inverse J^+. Solved by Cholesky in the smaller of the task (k x k) and joint
    (n x n) spaces, which give the same dq. Pure: the inputs are not changed.

    Args:
        J: task Jacobian (k, n).
        error: y* - y (k,).
        damping: lambda > 0.
        nullspace: optional joint step d (n,) for the null space.

    Returns:
        dq (n,).
    """
    J = np.ascontiguousarray(J, dtype=np.float64)
    e = np.ascontiguousarray(error, dtype=np.float64)
    d = None if nullspace is None else np.asarray(nullspace, dtype=np.float64)
    return _dls(J, e, damping, d, _Workspace(min(J.shape)))


class _Workspace:
    """Buffers of `_dls` for an (m, m) system: A, its diagonal (a view) and x (m,)."""

    def __init__(self, m: int):
        self.A = np.empty((m, m))
        self.diag = self.A.reshape(-1)[:: m + 1]
        self.x = np.empty(m)


def _dls(J: np.ndarray, e: np.ndarray, damping: float, d: np.ndarray | None, ws: _Workspace) -> np.ndarray:
    """`dls_step` on C-contiguous float64 J (k, n) and e (k,), in a workspace for m = min(k, n)."""
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


class _Joints:
    """Addresses and limits of the joints the solver moves (hinge or slide: one qpos and one dof each)."""

    def __init__(self, model: mujoco.MjModel, names: tuple[str, ...]):
        if not names or len(set(names)) != len(names):
            raise InvalidConfig(f"joints must be distinct joint names; got {names!r}")
        ids = [name_to_id(model, "joint", n) for n in names]
        types = [int(model.jnt_type[j]) for j in ids]  # mujoco 4 enums: compare as int
        for n, t in zip(names, types):
            if t not in (_HINGE, _SLIDE):
                raise InvalidConfig(f"joint {n!r} is not a hinge or slide joint; the IK moves only those")
        qadr = np.array([model.jnt_qposadr[j] for j in ids])
        dadr = np.array([model.jnt_dofadr[j] for j in ids])
        #: qpos entries of the joints: a slice where they are contiguous (faster to read and write).
        self.qsel = as_slice(qadr)
        #: Columns of J to keep; None where the joints' dofs are all of J's columns, in order.
        self.dadr = None if np.array_equal(dadr, np.arange(model.nv)) else dadr
        limited = np.array([bool(model.jnt_limited[j]) for j in ids])
        rng = model.jnt_range[ids]
        self.lo = np.where(limited, rng[:, 0], -np.inf)
        self.hi = np.where(limited, rng[:, 1], np.inf)
        # Restart seeds: hinges within [-pi, pi] (every angle once), slides within their range
        # (at 0 for a slide without limits).
        hinge = np.array([t == _HINGE for t in types])
        self.seed_lo = np.where(hinge, np.maximum(self.lo, -np.pi), np.where(limited, self.lo, 0.0))
        self.seed_hi = np.where(hinge, np.minimum(self.hi, np.pi), np.where(limited, self.hi, 0.0))


class _Difference:
    """a - b in a map's coordinates, the numbers `task_map.difference(a, b)` gives, for 1-D a and b.

    For a stock `Stack` (whose difference is each part's difference on its rows) only the rows of
    parts that override `difference` are treated, the rest subtracted at once; `Quaternion` parts
    apply their documented rule a - sign(a . b) b (sign 1 at 0, docs/taskmaps.md) directly. Both
    give the same numbers as the maps' own methods (tests/ik/test_dls.py checks it) at a fraction
    of the cost: numpy's general path costs as much as the map evaluation for one 4-vector.
    """

    def __init__(self, task_map: TaskMap):
        # Holds the stack's parts, never the map itself: the map is the key of the cache below.
        self.parts: tuple[tuple[TaskMap | None, slice], ...] | None = None
        if isinstance(task_map, Stack) and type(task_map).difference is Stack.difference:
            self.parts = tuple(
                (None if type(part).difference is Quaternion.difference else part, span)
                for part, span in zip(task_map.parts, task_map.slices.values())
                if type(part).difference is not TaskMap.difference
            )

    def __call__(self, task_map: TaskMap, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """task_map.difference(a, b) for the map this was built for, a and b (dim,)."""
        if self.parts is None:
            return np.ascontiguousarray(task_map.difference(a, b), dtype=np.float64)
        out = a - b
        for part, span in self.parts:
            if part is None:  # a quaternion
                if a[span] @ b[span] < 0.0:
                    out[span] = a[span] + b[span]
            else:
                out[span] = part.difference(a[span], b[span])
        return out


class _Setup(NamedTuple):
    """What a call needs that depends only on (model, task map, joint names), cached per task map."""

    model: weakref.ref[mujoco.MjModel]
    names: tuple[str, ...]
    joints: _Joints
    difference: _Difference


_SETUPS: weakref.WeakKeyDictionary[TaskMap, _Setup] = weakref.WeakKeyDictionary()


def _setup(model: mujoco.MjModel, task_map: TaskMap, joints: Sequence[str] | None) -> _Setup:
    """The joints called `joints` (default: the six UR5e arm joints) and the map's difference."""
    names = JOINT_NAMES if joints is None else tuple(joints)
    setup = _SETUPS.get(task_map)
    if setup is None or setup.model() is not model or setup.names != names:
        setup = _Setup(weakref.ref(model), names, _Joints(model, names), _Difference(task_map))
        _SETUPS[task_map] = setup
    return setup


def _positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidConfig(f"{name} must be a number; got {value!r}") from None
    if not (v >= 0.0 if allow_zero else v > 0.0):  # also rejects NaN
        raise InvalidConfig(f"{name} must be {'>= 0' if allow_zero else '> 0'}; got {value!r}")
    return v


def _count(name: str, value: int, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InvalidConfig(f"{name} must be an integer >= {minimum}; got {value!r}")
    return int(value)


def _finite(v: np.ndarray) -> bool:
    """Whether every entry of the 1-D float array v is finite.

    v . v is finite exactly when every entry is, unless the sum overflows; only then is each entry
    checked. One dot product costs a third of `np.isfinite(v).all()` on the short vectors of a step.
    """
    return math.isfinite(v.dot(v)) or bool(np.isfinite(v).all())


def _vector(name: str, value: ArrayLike, size: int, what: str) -> np.ndarray:
    """value as a finite float array of shape (size,); `what` (said of the size) goes into the error."""
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (size,):
        raise InvalidConfig(f"{name} has shape {v.shape}; expected ({size},) {what}")
    if not _finite(v):
        raise InvalidConfig(f"{name} must be finite; got {v!r}")
    return v


class _Problem:
    """Validated options of a solve; `bind` adds the call's data and target.

    Then: the residual e = W (y* - y), its Jacobian W J and the DLS step.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        task_map: TaskMap,
        *,
        weights: ArrayLike | None,
        damping: float,
        adaptive_damping: float,
        max_step: float,
        posture: ArrayLike | None,
        posture_gain: float,
        joints: Sequence[str] | None,
    ):
        self.model, self.task_map = model, task_map
        _, _, self.joints, self.difference = _setup(model, task_map, joints)
        self.weights = None
        if weights is not None:
            w = _vector("weights", weights, task_map.dim, "(one per row of the task map)")
            if (w < 0.0).any():
                raise InvalidConfig(f"weights must be >= 0; got {w!r}")
            self.weights, self.weight_rows = w, w[:, None]
        self.damping = _positive("damping", damping)
        self.adaptive_damping = _positive("adaptive_damping", adaptive_damping, allow_zero=True)
        self.max_step = _positive("max_step", max_step)
        n = self.joints.lo.shape[0]
        self.workspace = _Workspace(min(n, task_map.dim))
        self.posture = None if posture is None else _vector("posture", posture, n, "(one per moved joint)")
        self.posture_gain = _positive("posture_gain", posture_gain, allow_zero=True)

    def bind(self, data: mujoco.MjData, target: ArrayLike) -> _Problem:
        """Sets the data the call works in and its validated target (dim,); returns self."""
        self.data = data
        self.target = _vector("target", target, self.task_map.dim, "for the task map's rows")
        return self

    def current(self) -> np.ndarray:
        """A copy of the moved joints' positions in data (n,); raises InvalidConfig if not finite."""
        q = self.data.qpos[self.joints.qsel].copy()
        if not _finite(q):
            raise InvalidConfig(f"data.qpos holds non-finite joint positions {q!r}")
        return q

    def checked_value(self, value: TaskMapValue) -> TaskMapValue:
        """A caller's (y, J) as float64 arrays, J C-contiguous; raises InvalidConfig on wrong shapes."""
        y, J = value
        dim, nv = self.task_map.dim, self.model.nv
        if np.shape(y) != (dim,) or np.shape(J) != (dim, nv):
            raise InvalidConfig(
                f"initial_value has y {np.shape(y)} and J {np.shape(J)}; expected ({dim},) and ({dim}, {nv})"
            )
        return TaskMapValue(np.asarray(y, dtype=np.float64), np.ascontiguousarray(J, dtype=np.float64))

    def evaluate(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """Sets the joints to q in data, runs mj_kinematics + mj_comPos, returns (e, W J, ||e||)."""
        model, data = self.model, self.data
        data.qpos[self.joints.qsel] = q
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        y, J = self.task_map(model, data)
        return self.residual(
            TaskMapValue(y, np.ascontiguousarray(J, dtype=np.float64))
        )  # no copy for a stock map

    def residual(self, value: TaskMapValue) -> tuple[np.ndarray, np.ndarray, float]:
        """(e (k,), W J (k, n), ||e||) for a task-map value (y, J) of float64 arrays, J C-contiguous."""
        y, J = value
        e = self.difference(self.task_map, self.target, y)
        if self.joints.dadr is not None:
            J = np.ascontiguousarray(J[:, self.joints.dadr])  # fancy indexing may give F order
        if self.weights is not None:
            e = e * self.weights
            J = J * self.weight_rows
        err = math.sqrt(e.dot(e))
        return e, J, err if math.isfinite(err) else math.inf  # a NaN in y never reaches the result

    def step(self, q: np.ndarray, e: np.ndarray, J: np.ndarray, err: float) -> np.ndarray | None:
        """The next configuration q + dq, ||dq|| <= max_step, clipped to the limits; None if dq is not finite."""
        lam = self.damping + self.adaptive_damping * err * err
        d = None if self.posture is None else self.posture_gain * (self.posture - q)
        dq = _dls(J, e, lam, d, self.workspace)
        norm = math.sqrt(dq.dot(dq))
        if not math.isfinite(norm):
            return None
        if norm > self.max_step:
            dq *= self.max_step / norm
        dq += q
        return self.clip(dq)

    def clip(self, q: np.ndarray) -> np.ndarray:
        """q clipped to the joint limits, in place."""
        return np.minimum(np.maximum(q, self.joints.lo, out=q), self.joints.hi, out=q)


class IKStepper:
    """`ik_step` with its options checked once: for a control loop that takes one step per period.

    `IKStepper(model, task_map, **options)(data, target, initial_value)[0]` equals
    `ik_step(model, data, task_map, target, initial_value=initial_value, **options)`; the call also
    returns the residual the linearised map predicts after the step.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        task_map: TaskMap,
        *,
        weights: ArrayLike | None = None,
        damping: float = DEFAULT_DAMPING,
        adaptive_damping: float = DEFAULT_ADAPTIVE_DAMPING,
        max_step: float = DEFAULT_MAX_STEP,
        posture: ArrayLike | None = None,
        posture_gain: float = DEFAULT_POSTURE_GAIN,
        joints: Sequence[str] | None = None,
    ):
        self._problem = _Problem(
            model,
            task_map,
            weights=weights,
            damping=damping,
            adaptive_damping=adaptive_damping,
            max_step=max_step,
            posture=posture,
            posture_gain=posture_gain,
            joints=joints,
        )

    def __call__(
        self, data: mujoco.MjData, target: ArrayLike, initial_value: TaskMapValue | None = None
    ) -> tuple[np.ndarray, float]:
        """One step from the configuration in `data` (see `ik_step`).

        Returns:
            q_next: q + dq within the joint limits (n,).
            residual: ||W (y* - y) - W J (q_next - q)||, the error the linearised map predicts at q_next.
        """
        problem = self._problem.bind(data, target)
        q = problem.current()
        if initial_value is None:
            mujoco.mj_kinematics(problem.model, data)
            mujoco.mj_comPos(problem.model, data)
            initial_value = problem.task_map(problem.model, data)
        return self.step_from(q, problem.checked_value(initial_value), problem.target)

    def step_from(self, q: np.ndarray, value: TaskMapValue, target: np.ndarray) -> tuple[np.ndarray, float]:
        """The step of a call, from the moved joints' positions q (n,), the map's value (y, J) at q and
        the target (dim,), all taken as they are: nothing is checked.

        For a control loop that guarantees its inputs (float64 arrays of the right shapes, finite, J
        C-contiguous), as the environments do with values from the same map: the checks of a call
        cost a third of the step. q is not written. Returns (q_next, residual) as a call does.
        """
        problem = self._problem
        problem.target = target
        e, J, err = problem.residual(value)
        q_next = problem.step(q, e, J, err)
        if q_next is None:
            q_next = problem.clip(q.copy())
        r = e - J.dot(q_next - q)
        return q_next, math.sqrt(r.dot(r))


def ik_step(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    task_map: TaskMap,
    target: ArrayLike,
    *,
    initial_value: TaskMapValue | None = None,
    weights: ArrayLike | None = None,
    damping: float = DEFAULT_DAMPING,
    adaptive_damping: float = DEFAULT_ADAPTIVE_DAMPING,
    max_step: float = DEFAULT_MAX_STEP,
    posture: ArrayLike | None = None,
    posture_gain: float = DEFAULT_POSTURE_GAIN,
    joints: Sequence[str] | None = None,
) -> np.ndarray:
    """One linearised step from the configuration in `data`: q + dq within the joint limits (n,).

    The paper's formula q* = q + J^T (J J^T + lambda I)^{-1} (y* - y), with the damping, weights,
    posture term and step bound of `solve_ik`, for use inside a control loop (`IKStepper` checks
    the options once for many steps). `data.qpos` and `data.qvel` are not changed. With
    `initial_value` (the map's value at data's configuration, e.g. the one the environment
    computed this step) nothing is evaluated; without it the kinematics in `data` are refreshed
    (mj_kinematics + mj_comPos) and the map is evaluated. The step is taken from data's own q,
    even outside the limits; only the result is clipped. Options as in `solve_ik`; raises
    InvalidConfig on bad input.
    """
    stepper = IKStepper(
        model,
        task_map,
        weights=weights,
        damping=damping,
        adaptive_damping=adaptive_damping,
        max_step=max_step,
        posture=posture,
        posture_gain=posture_gain,
        joints=joints,
    )
    return stepper(data, target, initial_value)[0]


def solve_ik(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    task_map: TaskMap,
    target: ArrayLike,
    *,
    tol: float = DEFAULT_TOL,
    max_iters: int = DEFAULT_MAX_ITERS,
    restarts: int = DEFAULT_RESTARTS,
    seed: int = 0,
    weights: ArrayLike | None = None,
    damping: float = DEFAULT_DAMPING,
    adaptive_damping: float = DEFAULT_ADAPTIVE_DAMPING,
    max_step: float = DEFAULT_MAX_STEP,
    posture: ArrayLike | None = None,
    posture_gain: float = DEFAULT_POSTURE_GAIN,
    joints: Sequence[str] | None = None,
    initial_value: TaskMapValue | None = None,
) -> IKResult:
    r"""Joint positions q that bring task_map(q) to `target`, starting from the configuration in `data`.

    Iterates damped least-squares steps q <- clip(q + dq), dq = J^T (J J^T + lambda I)^{-1} W e with
    e = y* - y, adaptive damping lambda = damping + adaptive_damping ||W e||^2, ||dq|| <= max_step,
    until ||W e|| < tol. An attempt that stalls (error above STALL_RATIO times its value
    STALL_WINDOW iterations earlier) gives way to a restart from a random configuration within the
    limits, up to `restarts` times. Never raises on non-convergence and never returns NaN.

    `data` is the workspace: on return its qpos holds the returned q at the moved joints (other
    coordinates, such as a free object's, are never written) and its kinematics (mj_kinematics +
    mj_comPos) are up to date. Pass a scratch MjData where the physics state must stay untouched.

    Args:
        model, data: the MuJoCo model and the data holding the start configuration.
        task_map: the map phi (dim rows); a `Stack` for several maps.
        target: desired value y* (dim,).
        tol: convergence threshold on ||W e|| (units of the map's rows).
        max_iters: iterations per attempt.
        restarts: restarts from random seeds after a stalled attempt; 0 for a purely local solve.
        seed: seed of the restart configurations (the solve is deterministic).
        weights: per-row weights W (dim,), >= 0; default all ones.
        damping: damping floor lambda_0 > 0 (the paper's eps).
        adaptive_damping: lambda_e >= 0, the error-proportional part of the damping.
        max_step: largest ||dq||_2 per iteration.
        posture: optional joint positions (n,) pursued in the null space of the task.
        posture_gain: k of the posture step k (posture - q).
        joints: names of the hinge or slide joints to move; default the six UR5e arm joints.
        initial_value: the map's value at the start configuration, when the caller has it; the
            first evaluation is then skipped (and `data` is not touched if the start already meets tol).

    Returns:
        IKResult: the first converged iterate; if no attempt converges, the lowest-error iterate of
        the first attempt (the local least-squares compromise, not a far-away restart).

    Raises:
        InvalidConfig: a target, weight, posture or option of the wrong shape or value, or NaN.
        UnknownName: a joint name the model does not have.
    """
    problem = _Problem(
        model,
        task_map,
        weights=weights,
        damping=damping,
        adaptive_damping=adaptive_damping,
        max_step=max_step,
        posture=posture,
        posture_gain=posture_gain,
        joints=joints,
    ).bind(data, target)
    tol = _positive("tol", tol)
    max_iters = _count("max_iters", max_iters, 1)
    restarts = _count("restarts", restarts, 0)

    q = problem.current()
    if initial_value is not None and (q == problem.clip(q.copy())).all():  # used only within the limits
        e, J, err = problem.residual(problem.checked_value(initial_value))
        evaluated = None  # data not touched yet
    else:
        q = problem.clip(q)
        e, J, err = problem.evaluate(q)
        evaluated = q  # the configuration whose kinematics data holds
    history = [err]
    best_q, best_err = q, err  # over the first attempt, until one converges
    seeds: np.random.Generator | None = None
    for attempt in range(restarts + 1):
        if attempt > 0:
            if seeds is None:
                seeds = np.random.default_rng(seed)
            q = seeds.uniform(problem.joints.seed_lo, problem.joints.seed_hi)
            e, J, err = problem.evaluate(q)
            evaluated = q
            history.append(err)
        first = len(history) - 1
        for _ in range(max_iters):
            if err < tol:
                break
            if (
                attempt < restarts
                and len(history) - first > STALL_WINDOW
                and not err <= STALL_RATIO * history[-1 - STALL_WINDOW]
            ):
                break
            q_next = problem.step(q, e, J, err)
            if q_next is None:
                break
            q = evaluated = q_next
            e, J, err = problem.evaluate(q)
            history.append(err)
            if attempt == 0 and err < best_err:
                best_q, best_err = q, err
        if err < tol:
            best_q, best_err = q, err
            break
    if evaluated is not None and best_q is not evaluated:
        problem.evaluate(best_q)
    return IKResult(best_q.copy(), best_err, len(history) - 1, best_err < tol, tuple(history))
