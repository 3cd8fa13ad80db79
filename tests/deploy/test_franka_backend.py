"""FrankaBackend's call sequence against a stand-in `franky` module (tests/deploy/test_franky_sim.py runs
it against franky-sim): the realtime option reaches franky, a held target is not re-sent, a command
franky refuses is counted and recovered from without stopping the loop, a non-finite command never
reaches franky, close stops the motion and drops the connection; --no-franka-realtime is franka's."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from tsrl.cli import main
from tsrl.deploy.backends import FrankaBackend
from tsrl.exceptions import InvalidAction


class StandInRobot:
    """Records franky.Robot's calls; `move` raises franky's planner error on the calls in `refuse`."""

    def __init__(self, address, realtime_config):
        self.calls: list[tuple] = [("Robot", address, realtime_config)]
        self.refuse: set[int] = set()
        self.moves = 0
        self.relative_dynamics_factor = 1.0
        ROBOTS.append(self)

    def recover_from_errors(self):
        self.calls.append(("recover_from_errors",))
        return True

    def move(self, motion, asynchronous=False):
        self.moves += 1
        if self.moves in self.refuse:
            raise RuntimeError("Motion planner failed with error code -111")
        self.calls.append(("move", motion, asynchronous))


ROBOTS: list[StandInRobot] = []


@pytest.fixture
def franky(monkeypatch):
    module = types.ModuleType("franky")
    module.Robot = StandInRobot
    module.RealtimeConfig = types.SimpleNamespace(Enforce="Enforce", Ignore="Ignore")
    module.RealtimeException = type("RealtimeException", (Exception,), {})
    module.Exception = type("Exception", (Exception,), {})
    module.JointMotion = lambda q: ("JointMotion", tuple(q))
    module.JointStopMotion = lambda: ("JointStopMotion",)
    monkeypatch.setitem(sys.modules, "franky", module)
    ROBOTS.clear()
    return module


def test_the_realtime_option_reaches_franky(franky):
    FrankaBackend("10.0.0.2").connect()
    FrankaBackend("127.0.0.2", realtime=False).connect()
    assert [r.calls[0] for r in ROBOTS] == [
        ("Robot", "10.0.0.2", "Enforce"),
        ("Robot", "127.0.0.2", "Ignore"),
    ]


def test_held_targets_are_not_resent_and_a_refused_command_does_not_stop_the_loop(franky):
    backend = FrankaBackend("127.0.0.2", realtime=False)
    backend.connect()
    robot = ROBOTS[0]
    robot.refuse = {3}  # franky's third move call fails
    a, b, c = np.zeros(7), np.full(7, 0.01), np.full(7, 0.02)
    for q in (a, a, a, b, b, c, c, c):
        backend.send(q)
    moves = [call[1][1] for call in robot.calls if call[0] == "move"]
    # a once (held twice), b once, c refused once, then sent afresh once and held.
    assert moves == [tuple(a), tuple(b), tuple(c)] and robot.moves == 4
    assert backend.failed_commands == 1
    assert [call[0] for call in robot.calls].count("recover_from_errors") == 2  # at connect and after
    with pytest.raises(InvalidAction, match="not sent"):
        backend.send(np.array([0.0, np.nan, 0, 0, 0, 0, 0]))
    assert robot.moves == 4
    backend.close()
    assert robot.calls[-1] == ("move", ("JointStopMotion",), False) and backend._robot is None
    backend.close()  # a second close does nothing


def test_no_franka_realtime_is_the_franka_backends_option(capsys, tmp_path):
    code = main(["deploy", str(tmp_path), "--no-franka-realtime"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err == (
        "tsrl: error: --no-franka-realtime is the franka backend's; accepted with --backend franka"
    )
