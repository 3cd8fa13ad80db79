"""The UR backend's calls to ur-rtde, checked with stand-in `rtde_control` / `rtde_receive` modules
(ur-rtde's documented Python API, recorded call by call; the backend is untried on a controller):
servoJ with its timing at every servo tick, each tick paced by waitPeriod then initPeriod, and
servoStop then stopScript on close."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from tsrl.deploy import Controller, ControllerOptions
from tsrl.deploy.backends import BackendError, UrRtdeBackend
from tsrl.deploy.loop import run_episodes


class Robot:
    """A UR controller as the two interfaces see it: each servoJ target is reached by the next read."""

    def __init__(self, q: np.ndarray):
        self.q = np.array(q, dtype=np.float64)
        self.calls: list[tuple] = []
        self.clock = 0


def stand_in_modules(robot: Robot, answer: bool = True) -> dict[str, types.ModuleType]:
    class RTDEReceiveInterface:
        def __init__(self, address: str):
            if not answer:
                raise RuntimeError("Timeout connecting to UR dashboard server")
            robot.calls.append(("RTDEReceiveInterface", address))

        def getActualQ(self) -> list[float]:
            robot.calls.append(("getActualQ",))
            return robot.q.tolist()

        def getActualQd(self) -> list[float]:
            return [0.0] * len(robot.q)

    class RTDEControlInterface:
        def __init__(self, address: str):
            robot.calls.append(("RTDEControlInterface", address))

        def initPeriod(self) -> int:
            robot.clock += 1
            robot.calls.append(("initPeriod",))
            return robot.clock

        def waitPeriod(self, t_start: int) -> None:
            robot.calls.append(("waitPeriod", t_start))

        def servoJ(self, q, velocity, acceleration, dt, lookahead_time, gain) -> bool:
            assert all(isinstance(v, float) for v in q)  # plain floats, as pybind11's vector<double>
            robot.calls.append(("servoJ", velocity, acceleration, dt, lookahead_time, gain))
            robot.q = np.array(q)
            return True

        def servoStop(self) -> None:
            robot.calls.append(("servoStop",))

        def stopScript(self) -> None:
            robot.calls.append(("stopScript",))

    control, receive = types.ModuleType("rtde_control"), types.ModuleType("rtde_receive")
    control.RTDEControlInterface = RTDEControlInterface  # type: ignore[attr-defined]
    receive.RTDEReceiveInterface = RTDEReceiveInterface  # type: ignore[attr-defined]
    return {"rtde_control": control, "rtde_receive": receive}


def test_the_ur_backend_servos_at_its_period_paces_each_tick_and_stops_on_close(ur5e_reach, monkeypatch):
    controller = Controller.from_export(ur5e_reach, ControllerOptions(servo_period=0.002))
    home = np.array(controller.contract.robot.home_q)
    robot = Robot(home)
    for name, module in stand_in_modules(robot).items():
        monkeypatch.setitem(sys.modules, name, module)
    backend = UrRtdeBackend("192.0.2.10")
    goal = controller.sample_goal(0)
    (result,) = run_episodes(controller, backend, [0], [goal])
    calls = [c[0] for c in robot.calls]
    assert robot.calls[:3] == [
        ("RTDEReceiveInterface", "192.0.2.10"),
        ("RTDEControlInterface", "192.0.2.10"),
        ("initPeriod",),
    ]
    ticks = 50 * 20  # 50 policy steps of 40 ms, a servo tick every 2 ms
    servo = [c for c in robot.calls if c[0] == "servoJ"]
    assert len(servo) == ticks and set(servo) == {("servoJ", 0.0, 0.0, 0.002, 0.1, 300.0)}
    # every servoJ is followed by waitPeriod(the last initPeriod's start) and a new initPeriod
    body = calls[3 : calls.index("servoStop")]
    tick_calls = [c for c in body if c != "getActualQ"]
    assert tick_calls == ["servoJ", "waitPeriod", "initPeriod"] * ticks
    waits = [c for c in robot.calls if c[0] == "waitPeriod"]
    assert [w[1] for w in waits] == list(range(1, ticks + 1))
    assert calls[-2:] == ["servoStop", "stopScript"]
    assert result.steps == 50 and not np.allclose(robot.q, home)  # the stand-in arm was moved


def test_a_ur_controller_that_does_not_answer_is_one_line_and_nothing_is_sent(monkeypatch):
    robot = Robot(np.zeros(6))
    for name, module in stand_in_modules(robot, answer=False).items():
        monkeypatch.setitem(sys.modules, name, module)
    backend = UrRtdeBackend("192.0.2.10")
    with pytest.raises(BackendError, match=r"no answer from 192.0.2.10 .*Timeout.*the arm was not moved"):
        backend.connect()
    assert robot.calls == []
