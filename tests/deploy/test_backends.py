"""The RobotBackend conformance test, run against MujocoBackend (and against a UR or Franka arm where
TSRL_UR_ADDRESS / TSRL_FRANKA_ADDRESS name one: it then moves the last joint by 0.01 rad); the MuJoCo
backend's latency, noise and dropped messages; shadow mode; joint mismatches refused."""

from __future__ import annotations

import itertools
import os

import numpy as np
import pytest

from tsrl.deploy.backends import (
    FrankaBackend,
    MujocoBackend,
    ShadowBackend,
    UrRtdeBackend,
    check_backend,
)
from tsrl.deploy.contract import read_contract
from tsrl.exceptions import InvalidAction, InvalidConfig


def backends(export):
    """The backends to check: MuJoCo always; a real arm where its address is given."""
    made = [MujocoBackend(export)]
    if os.environ.get("TSRL_UR_ADDRESS"):
        made.append(UrRtdeBackend(os.environ["TSRL_UR_ADDRESS"]))
    if os.environ.get("TSRL_FRANKA_ADDRESS"):
        made.append(FrankaBackend(os.environ["TSRL_FRANKA_ADDRESS"]))
    return made


def conformance(backend) -> None:
    """What the deploy loop relies on, for any backend: names, period, a finite state on a clock that
    moves on (by exactly the periods waited on MuJoCo's simulated clock), holding still when sent the
    measured pose, a small move when sent one. Nothing depends on the machine's speed: on a wall clock
    the move is waited for (up to 2,000 periods), not timed."""
    n = len(backend.joint_names)
    assert n >= 1 and len(set(backend.joint_names)) == n
    assert backend.period > 0
    backend.connect()
    try:
        backend.reset(0)
        state = backend.read_state()
        assert state.q.shape == state.qd.shape == (n,)
        assert np.isfinite(state.q).all() and np.isfinite(state.qd).all()
        start, t0 = state.q.copy(), backend.now()
        for _ in range(100):  # hold the measured pose for 100 periods
            backend.send(start)
            backend.wait()
        held = backend.read_state()
        if isinstance(backend, MujocoBackend):  # simulated time: the periods waited, exactly
            assert backend.now() - t0 == pytest.approx(100 * backend.period)
        else:  # a wall clock: it moved on; by how much is the machine's, so not checked
            assert backend.now() > t0
        assert held.time >= state.time
        assert np.abs(held.q - start).max() < 0.01  # rad: it held still
        target = start.copy()
        target[-1] += 0.01  # the last joint (a wrist), 0.01 rad, in 0.5 s
        for i in range(1, 251):
            backend.send(start + (target - start) * min(i / 250, 1.0))
            backend.wait()
        for i in range(2000):  # 250 periods, then on until the wrist is there (a wall clock's arm
            backend.send(target)  # moves as fast as its machine runs it)
            backend.wait()
            moved = backend.read_state()
            if i >= 249 and abs(moved.q[-1] - target[-1]) < 0.003:
                break
        assert np.isfinite(moved.q).all() and abs(moved.q[-1] - target[-1]) < 0.003
        assert np.abs(moved.q[:-1] - start[:-1]).max() < 0.01
    finally:
        backend.close()


def test_conformance(ur5e_reach):
    for backend in backends(ur5e_reach):
        check_backend(backend, read_contract(ur5e_reach))
        conformance(backend)


def test_conformance_of_the_panda(panda_pick_place):
    backend = MujocoBackend(panda_pick_place)
    conformance(backend)
    state = backend.read_state()
    assert set(state.objects) == {"box"} and state.objects["box"].shape == (13,)


def test_latency_delays_every_command_by_whole_periods(ur5e_reach):
    backend = MujocoBackend(ur5e_reach, latency=0.04)  # 20 periods of 2 ms
    backend.connect()
    backend.reset(0)
    q = backend.read_state().q
    for i in range(30):
        backend.send(q)
        backend.wait()
        assert backend.applied == max(0, i + 1 - 20)


def test_noise_and_dropped_messages_are_seeded_and_measured(ur5e_reach):
    def readings(seed):
        backend = MujocoBackend(ur5e_reach, joint_noise=0.01, drop_rate=0.2, seed=seed)
        backend.connect()
        backend.reset(0)
        out = []
        for _ in range(500):
            out.append(backend.read_state())
            backend.send(out[-1].q * 0 + out[0].q)
            backend.wait()
        return out, backend

    states, backend = readings(1)
    again, _ = readings(1)
    assert all(np.array_equal(a.q, b.q) for a, b in zip(states, again))  # deterministic given the seed
    repeats = sum(a is b for a, b in itertools.pairwise(states))
    assert 60 < repeats < 140  # ~20% of 499 reads return the previous state again
    assert 300 < backend.applied < 450  # ~80% of 500 commands arrive
    fresh = [s for s, prev in zip(states[1:], states) if s is not prev]
    noise = np.array([s.q - backend.data.qpos[backend._qpos] for s in fresh[-50:]])
    assert 0.005 < noise.std() < 0.02


def test_a_command_with_nan_never_reaches_the_simulator(ur5e_reach):
    backend = MujocoBackend(ur5e_reach)
    with pytest.raises(InvalidAction, match="not sent"):
        backend.send(np.full(6, np.nan))
    assert backend.applied == 0


def test_shadow_mode_sends_nothing(ur5e_reach):
    sim = MujocoBackend(ur5e_reach)
    shadow = ShadowBackend(sim)
    shadow.connect()
    shadow.reset(0)
    start = shadow.read_state().q
    for _ in range(100):
        shadow.send(start + 1.0)  # would move every joint by 1 rad
        shadow.wait()
    assert shadow.sent == 100 and sim.applied == 0
    assert np.abs(shadow.read_state().q - start).max() < 1e-3


def test_a_backend_with_other_joints_is_refused_in_one_line(ur5e_reach, panda_pick_place):
    ur, panda = read_contract(ur5e_reach), read_contract(panda_pick_place)
    with pytest.raises(InvalidConfig) as err:
        check_backend(FrankaBackend("192.0.2.1"), ur)  # not connected: the names alone are compared
    message = str(err.value)
    assert "\n" not in message and "joint1" in message and "shoulder_pan" in message and "(7)" in message
    with pytest.raises(InvalidConfig, match=r"\(6\); the contract's robot has .* \(7\)"):
        check_backend(UrRtdeBackend("192.0.2.1"), panda)
    check_backend(MujocoBackend(panda_pick_place), panda)


def test_another_model_file_of_the_arm_can_be_the_simulated_robot(ur5e_reach, tmp_path):
    import shutil

    copy = tmp_path / "model"
    shutil.copytree(ur5e_reach / "model", copy)  # the same arm, from another place
    backend = MujocoBackend(ur5e_reach, scene=copy / "scenes" / "reach.xml")
    check_backend(backend, read_contract(ur5e_reach))
    conformance(backend)
