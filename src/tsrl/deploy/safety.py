"""The safety layer's joint limiter (servo-rate joint commands within position, speed and acceleration
limits) and its rule for commands the robot refuses (`RefusedCommands`).

A policy step sets a *reference*: the step's target q* (within the joint limits) at once (the
default: as the training environment sets its servos' targets), or with `ramp` from the command's
position c0 at that time t_k to q*, linearly over one control period T, then held:

    r(t) = c0 + min((t - t_k) / T, 1) (q* - c0),   v_r = (q* - c0) / T until t_k + T, then 0
    (at once: c0 = q*, v_r = 0).

Each servo tick (one call of `step`, period h) moves the command q toward r per joint:

    v = v_r + s(r(t) - v_r h - q)         track the reference, closing the gap as fast as a stop allows
    v = clip(v, -v_max, v_max)
    v = clip(v, -s(q - lo), s(hi - q))    never so fast toward a limit that it cannot stop before it
    v = clip(v, v_prev - a_max h, v_prev + a_max h)
    q = q + v h

with s(d) the largest signed speed from which ticks of deceleration a_max h stop within d (exact for
the ticks, `_stop_speed`). Hence, between successive commands, whatever the
targets and whenever `step` is called: |q_{i+1} - q_i| <= v_max h, |q_{i+1} - 2 q_i + q_{i-1}| <=
a_max h^2, and lo <= q <= hi (the invariant |v| <= s(distance to the limit ahead) survives a tick of
full deceleration: s(d - s(d) h) = s(d) - a_max h, as the ticks from s(d) cover d exactly). When the limits allow it the command is the
reference itself: the target (or, with `ramp`, linear interpolation between policy targets).
"""

from __future__ import annotations

import numpy as np

#: What a policy step's target was bounded by (the controller reports it).
JOINT_LIMIT = "joint_limit"
#: A servo command the robot refused (RobotBackend.send answered why): the step's fault.
COMMAND_REFUSED = "command_refused"
#: Refused commands in a row after which a deployment stops (RefusedCommands).
MAX_REFUSED_IN_ROW = 5


class RefusedCommands:
    """The safety layer's rule for servo commands the robot refuses (e.g. franky's "Motion planner
    failed"): each one is a fault of its policy step, after which the command holds (the limiter stops as
    fast as its limits allow: JointLimiter.hold); `max_in_row` refused in a row stop the deployment with
    a one-line reason (`refused` returns it). An accepted command resets the run of refusals.
    """

    def __init__(self, max_in_row: int = MAX_REFUSED_IN_ROW):
        if max_in_row < 1:
            raise ValueError(f"max_in_row must be >= 1; got {max_in_row}")
        self.max_in_row = max_in_row
        self.total = 0
        self.in_row = 0

    def accepted(self) -> None:
        """The robot took a command."""
        self.in_row = 0

    def refused(self, why: str) -> str | None:
        """The robot refused a command (`why`, its one-line answer); the reason to stop (one line), or
        None to hold and go on."""
        self.total += 1
        self.in_row += 1
        if self.in_row < self.max_in_row:
            return None
        return (
            f"the robot refused {self.in_row} commands in a row (the last: {why}); stopped after "
            f"{self.max_in_row} in a row"
        )


class JointLimiter:
    """Servo-rate joint commands that follow the policy's targets within the limits (module docstring).

    Args:
        lower, upper: position limits (n,) [rad or m], finite.
        max_speed: (n,) > 0 [rad/s or m/s]; max_acceleration: (n,) > 0 [rad/s^2 or m/s^2].
        servo_period: h [s], the time one `step` advances the command by.
        control_period: T [s], the time a policy target's reference takes to reach it (ramp).
        ramp: the reference ramps to each target over T (smooth, it lags the target by up to T);
            False: the reference is the target at once (the command moves as fast as the limits
            allow, as close as the limits let it come to the training environment's servo targets).
    """

    def __init__(
        self,
        lower: np.ndarray,
        upper: np.ndarray,
        max_speed: np.ndarray,
        max_acceleration: np.ndarray,
        servo_period: float,
        control_period: float,
        ramp: bool = False,
    ):
        self.lower = np.asarray(lower, dtype=np.float64).copy()
        self.upper = np.asarray(upper, dtype=np.float64).copy()
        self.max_speed = np.asarray(max_speed, dtype=np.float64).copy()
        self.max_acceleration = np.asarray(max_acceleration, dtype=np.float64).copy()
        n = self.lower.size
        for name, v in (
            ("upper", self.upper),
            ("max_speed", self.max_speed),
            ("max_acceleration", self.max_acceleration),
        ):
            if v.shape != (n,):
                raise ValueError(f"{name} has shape {v.shape}; expected ({n},)")
        if not (
            np.isfinite(self.lower).all()
            and np.isfinite(self.upper).all()
            and (self.lower < self.upper).all()
        ):
            raise ValueError("joint limits must be finite with lower < upper")
        if not ((self.max_speed > 0).all() and (self.max_acceleration > 0).all()):
            raise ValueError("speed and acceleration limits must be > 0")
        if not (servo_period > 0 and control_period > 0):
            raise ValueError("servo and control periods must be > 0")
        self.servo_period, self.control_period = float(servo_period), float(control_period)
        self.ramp = ramp
        h, a = self.servo_period, self.max_acceleration
        self._ah = a * h  # speed change allowed per tick
        self._half_ah = 0.5 * self._ah
        self._two_over_ah2 = 2.0 / (a * h * h)
        self._v_low = -self.max_speed
        self._limits = np.stack([self.upper, self.lower])
        self._gaps = np.empty((3, n))
        self.q = np.zeros(n)  # the last command
        self.v = np.zeros(n)  # its velocity over the last tick
        self._c0 = np.zeros(n)  # reference: from c0 at t_k to target over one control period
        self._target = np.zeros(n)
        self._v_ref = np.zeros(n)
        self._delta = np.zeros(n)  # target - c0
        self._tick_fraction = self.servo_period / self.control_period
        self._t_k = 0.0
        self._ready = False

    @property
    def ready(self) -> bool:
        """Whether `reset` has given the limiter its starting position."""
        return self._ready

    def reset(self, q: np.ndarray, t: float) -> None:
        """At rest at q (n,) (clipped to the limits) from time t on, holding it."""
        self.q = np.clip(np.asarray(q, dtype=np.float64), self.lower, self.upper)
        self.v = np.zeros_like(self.q)
        self._ready = True
        self._set_reference(self.q.copy(), t)

    def set_target(self, q_target: np.ndarray, t: float) -> tuple[np.ndarray, bool]:
        """A policy step at time t: the reference from the command's position to q_target (n,).

        Returns the target clipped to the joint limits and whether the clip changed it.
        """
        self._check_ready()
        target = np.minimum(np.maximum(q_target, self.lower), self.upper)
        self._set_reference(target, t)
        return target.copy(), bool((target != q_target).any())

    def hold(self, t: float) -> np.ndarray:
        """Stops as fast as the limits allow and holds there: the reference is the stop point. Returns it."""
        self._check_ready()
        stop = self.q + self.v * np.abs(self.v) / (2 * self.max_acceleration)
        target = np.minimum(np.maximum(stop, self.lower), self.upper)
        self._set_reference(target, t, ramp=False)  # the stop point at once
        return target.copy()

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The reference position and velocity (n,) at time t."""
        T = self.control_period
        s = (t - self._t_k) / T
        if s >= 1.0:
            return self._target, np.zeros_like(self._target)
        s = max(s, 0.0)
        return self._c0 + s * (self._target - self._c0), self._v_ref

    def step(self, t: float) -> np.ndarray:
        """The next servo command (n,) at time t: one tick of period h toward the reference (a new array).

        Written for the servo rate (numpy's np.clip costs three minimum/maximum calls; views, no copies).
        """
        self._check_ready()
        h = self.servo_period
        q, v_prev = self.q, self.v
        gaps = self._gaps
        # Row 0: the gap to the reference at the previous tick's time, r(t) - v_r h - q (on the
        # reference, v = v_r); rows 1, 2: to the upper and lower limits. One vectorised stop speed.
        s = (t - self._t_k) / self.control_period
        if s >= 1.0:
            np.subtract(self._target, q, out=gaps[0])
        else:
            np.multiply(self._delta, max(s, 0.0) - self._tick_fraction, out=gaps[0])
            gaps[0] += self._c0
            gaps[0] -= q
        np.subtract(self._limits, q, out=gaps[1:])
        stop = self._stop_speed(gaps)
        v = stop[0]
        if s < 1.0:
            v += self._v_ref
        np.minimum(v, self.max_speed, out=v)
        np.minimum(v, stop[1], out=v)
        np.maximum(v, self._v_low, out=v)
        np.maximum(v, stop[2], out=v)
        np.minimum(v, v_prev + self._ah, out=v)
        np.maximum(v, v_prev - self._ah, out=v)
        v *= h
        v += q  # q_next
        np.minimum(v, self.upper, out=v)  # no-ops but for round-off
        np.maximum(v, self.lower, out=v)
        self.v = (v - q) / h
        self.q = v
        return v.copy()

    def _stop_speed(self, d: np.ndarray) -> np.ndarray:
        """s(d): the largest signed speed from which ticks of deceleration a_max h stop within d (per
        entry; d (n,) or (k, n)).

        From speed v the ticks cover h (v + (v - a h) + ... + (v - m a h)), m = floor(v / (a h)); that
        is d where m = floor(sqrt(1/4 + 2 |d| / (a h^2)) - 1/2) and v = |d| / (h (m + 1)) + a h m / 2.
        """
        ad = np.abs(d)
        m = np.sqrt(0.25 + ad * self._two_over_ah2)
        m -= 0.5
        np.floor(m, out=m)
        s = ad / (m + 1.0)
        s /= self.servo_period
        m *= self._half_ah
        s += m
        return np.copysign(s, d, out=s)

    def _set_reference(self, target: np.ndarray, t: float, ramp: bool | None = None) -> None:
        """The reference from time t: a ramp from the command's position to `target` over one control
        period, or (ramp False) the target at once; `ramp` None: the limiter's setting."""
        self._c0[:] = self.q if (self.ramp if ramp is None else ramp) else target
        self._target[:] = target
        np.subtract(target, self._c0, out=self._delta)
        np.divide(self._delta, self.control_period, out=self._v_ref)
        self._t_k = float(t)

    def _check_ready(self) -> None:
        if not self._ready:
            raise RuntimeError("JointLimiter.reset(q, t) first: the limiter starts at rest at the measured q")
