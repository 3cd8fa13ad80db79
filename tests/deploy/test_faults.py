"""Fault injection over 10,000 policy cycles (200 episodes) of an exported policy on the MuJoCo backend:
NaN joint readings, 200 ms stalls, goals outside the workspace and IK steps far beyond the speed limit.
Every servo command of every cycle stays within the joint, speed and acceleration limits, every TCP
target within the workspace box, and every injected fault is reported. Time is the simulation's."""

from __future__ import annotations

import numpy as np

from tsrl.deploy.backends import MujocoBackend
from tsrl.deploy.controller import (
    GOAL_OUTSIDE_WORKSPACE,
    NONFINITE_STATE,
    Controller,
    ControllerOptions,
)

CYCLES = 10_000


class JumpingIK:
    """The controller's IK, but on the given cycles its step asks for every joint 2 rad away."""

    def __init__(self, ik, cycles: set[int]):
        self.ik, self.cycles, self.calls = ik, cycles, 0

    def step(self, q, value, target):
        q_next, residual = self.ik.step(q, value, target)
        self.calls += 1
        if self.calls in self.cycles:
            return q + 2.0 * np.where(self.calls % 2, 1.0, -1.0), residual
        return q_next, residual


def test_no_command_leaves_the_limits_under_injected_faults(ur5e_reach):
    rng = np.random.default_rng(0)
    backend = MujocoBackend(ur5e_reach, seed=0)
    controller = Controller.from_export(ur5e_reach, ControllerOptions(servo_period=backend.period))
    jumps = set(rng.choice(np.arange(1, CYCLES), 300, replace=False).tolist())
    controller.interface._ik = JumpingIK(controller.interface._ik, jumps)  # the IK step the interface takes
    limiter = controller.limiter
    h, T = backend.period, controller.control_period
    ticks = round(T / h)
    steps = controller.contract.task.episode_steps
    low, high = controller.workspace
    far_goal = np.array([-1.5, 0.9, 1.2])  # outside the workspace box on every axis
    reported = {NONFINITE_STATE: 0, GOAL_OUTSIDE_WORKSPACE: 0}
    injected = {NONFINITE_STATE: 0, GOAL_OUTSIDE_WORKSPACE: 0, "stall": 0}
    backend.connect()
    cycle_index = 0
    for episode in range(CYCLES // steps):
        backend.reset(episode)
        goal = far_goal if episode % 4 == 3 else controller.sample_goal(episode)
        controller.reset(backend.read_state().q, backend.now(), goal)
        commands = []
        for _ in range(steps):
            cycle_index += 1
            if rng.random() < 0.01:  # a 200 ms stall: no policy step, no command; the servos hold
                injected["stall"] += 1
                for _ in range(round(0.2 / h)):
                    backend.wait()
            state = backend.read_state()
            q = state.q.copy()
            nan = rng.random() < 0.02
            if nan:
                q[rng.integers(q.size)] = np.nan
                injected[NONFINITE_STATE] += 1
            injected[GOAL_OUTSIDE_WORKSPACE] += episode % 4 == 3 and not nan  # a held step checks no goal
            controller.act(q, state.qd, state.objects, t=backend.now(), stamp=state.time)
            cycle = controller.last
            for fault in reported:
                reported[fault] += fault in cycle.faults
            if not cycle.held:  # the TCP target the IK was given is within the box
                assert (cycle.ik_target[:3] >= low).all() and (cycle.ik_target[:3] <= high).all()
            assert np.isfinite(cycle.q_target).all()
            for _ in range(ticks):
                command = controller.interpolate(backend.now() + h)
                commands.append(command)
                backend.send(command)  # raises on NaN: none may reach the simulator
                backend.wait()
        c = np.array(commands)
        # Every command of the episode, against the limiter's limits (contract limits less the margin).
        assert (c >= limiter.lower - 1e-12).all() and (c <= limiter.upper + 1e-12).all()
        assert (np.abs(np.diff(c, axis=0)) <= limiter.max_speed * h * (1 + 1e-9)).all()
        assert (np.abs(np.diff(c, 2, axis=0)) <= limiter.max_acceleration * h * h * (1 + 1e-6)).all()
    assert cycle_index == CYCLES
    assert injected["stall"] > 50 and len(jumps) == 300
    assert reported == {k: injected[k] for k in reported}  # every NaN reading and far goal reported
