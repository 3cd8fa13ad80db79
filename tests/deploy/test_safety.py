"""The joint limiter: successive servo commands stay within position, speed and acceleration limits
whatever the targets and whenever it is called (far targets, limits, reversals, holds, late or missing
policy steps and servo ticks), and follow the linear interpolation between targets where the limits
allow it."""

from __future__ import annotations

import numpy as np
import pytest

from tsrl.deploy.safety import JointLimiter

H, T = 0.002, 0.04
LOWER = np.array([-1.0, -0.2, -3.0])
UPPER = np.array([1.0, 0.3, 3.0])
V_MAX = np.array([1.0, 2.0, 3.14])
A_MAX = np.array([5.0, 15.0, 10.0])


def limiter(ramp: bool = False) -> JointLimiter:
    return JointLimiter(LOWER, UPPER, V_MAX, A_MAX, H, T, ramp)


def assert_within_limits(commands: np.ndarray) -> None:
    """Commands (k, n) one servo tick apart: positions, speeds and accelerations within the limits."""
    assert (commands >= LOWER - 1e-12).all() and (commands <= UPPER + 1e-12).all()
    speed = np.abs(np.diff(commands, axis=0)) / H
    accel = np.abs(np.diff(commands, 2, axis=0)) / H**2
    assert (speed <= V_MAX * (1 + 1e-9)).all(), (speed / V_MAX).max()
    assert (accel <= A_MAX * (1 + 1e-6)).all(), (accel / A_MAX).max()


@pytest.mark.parametrize("ramp", [False, True])
def test_random_targets_holds_and_stalls_stay_within_every_limit(ramp):
    rng = np.random.default_rng(0)
    lim = limiter(ramp)
    lim.reset(np.zeros(3), 0.0)
    t, next_step, commands = 0.0, 0.0, []
    for _ in range(30_000):
        if t >= next_step - 1e-12:
            kind = rng.integers(4)
            if kind == 0:  # anywhere, far beyond the limits included
                lim.set_target(rng.uniform(LOWER - 2, UPPER + 2), t)
            elif kind == 1:  # a limit
                lim.set_target(np.where(rng.random(3) < 0.5, LOWER, UPPER), t)
            elif kind == 2:
                lim.hold(t)
            else:  # a small step
                lim.set_target(lim.q + rng.normal(0, 0.02, 3), t)
            # The next policy step on time, early, late, or after a stall of 10 periods.
            next_step = t + T * rng.choice([1.0, 0.5, 1.5, 10.0], p=[0.7, 0.1, 0.1, 0.1])
        commands.append(lim.step(t))
        # Servo ticks on time, or late (the command still moves one tick's worth per call).
        t += H * rng.choice([1.0, 3.0], p=[0.95, 0.05])
    assert_within_limits(np.array(commands))


def test_targets_within_the_limits_are_met_at_once_or_by_linear_interpolation():
    lim = limiter()
    lim.reset(np.zeros(3), 0.0)
    lim.set_target(np.array([1e-6, -1e-6, 1e-6]), 0.0)  # a step within a tick's speed change
    np.testing.assert_allclose(lim.step(H), [1e-6, -1e-6, 1e-6], atol=1e-18)
    np.testing.assert_allclose(lim.step(2 * H), [1e-6, -1e-6, 1e-6], atol=1e-18)  # and held
    lim = limiter(ramp=True)
    lim.reset(np.zeros(3), 0.0)
    step = np.array([0.0002, -0.0002, 0.0002])  # slow: a speed change of less than a_max h
    lim.set_target(step, 0.0)
    commands = np.array([lim.step(i * H) for i in range(1, 21)])  # ticks at h, 2h, ..., T
    expected = np.outer(np.arange(1, 21) / 20, step)
    np.testing.assert_allclose(commands, expected, atol=1e-15)


def test_a_far_target_is_reached_at_rest_and_bounded_by_speed_and_acceleration():
    lim = limiter()
    lim.reset(np.zeros(3), 0.0)
    goal = np.array([0.9, 0.29, 2.9])
    lim.set_target(goal, 0.0)
    commands = np.array([lim.step(i * H) for i in range(1, 3001)])  # 6 s
    assert_within_limits(commands)
    np.testing.assert_allclose(commands[-1], goal, atol=1e-12)
    np.testing.assert_allclose(lim.v, 0.0, atol=1e-9)
    speed = np.abs(np.diff(commands, axis=0)).max(axis=0) / H
    np.testing.assert_allclose(speed, V_MAX, rtol=1e-6)  # the long moves get to full speed


def test_hold_stops_the_command_and_keeps_it_still():
    lim = limiter()
    lim.reset(np.zeros(3), 0.0)
    lim.set_target(UPPER, 0.0)
    t = 0.0
    for _ in range(100):  # moving fast toward the upper limits
        t += H
        lim.step(t)
    stop = lim.hold(t)
    commands = np.array([lim.step(t + i * H) for i in range(1, 500)])
    assert_within_limits(commands)
    np.testing.assert_allclose(commands[-1], stop, atol=1e-9)
    np.testing.assert_allclose(lim.v, 0.0, atol=1e-9)


def test_set_target_reports_a_target_outside_the_joint_limits():
    lim = limiter()
    lim.reset(np.zeros(3), 0.0)
    target, clipped = lim.set_target(np.array([2.0, 0.0, 0.0]), 0.0)
    assert clipped and target[0] == 1.0
    assert lim.set_target(np.zeros(3), T)[1] is False


def test_reset_is_required_and_limits_are_checked():
    with pytest.raises(RuntimeError, match="reset"):
        limiter().step(0.0)
    with pytest.raises(ValueError, match="> 0"):
        JointLimiter(LOWER, UPPER, -V_MAX, A_MAX, H, T)
    with pytest.raises(ValueError, match="finite"):
        JointLimiter(np.array([-np.inf, 0, 0]), UPPER, V_MAX, A_MAX, H, T)
