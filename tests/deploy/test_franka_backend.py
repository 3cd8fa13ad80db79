"""FrankaBackend's call sequence against a stand-in `franky` module (tests/deploy/test_franky_sim.py runs
it against franky-sim): the realtime option reaches franky, a held target is not re-sent, a command
franky refuses is counted, recovered from and answered with franky's message, a non-finite command
never reaches franky, close stops the motion and drops the connection; --no-franka-realtime is
franka's. With a gripper (a gripper task's export), the Franka Hand through franky's `Gripper`: its
width is the state's tool, a new width is sent without waiting (move to open, grasp to close), a held
one is not re-sent, a width out of range or NaN never reaches franky. In `tsrl deploy`, a refused command is a fault the safety layer handles: the commands hold
until the next policy step (the log says which, and replays to the same commands), and 5 refused in a
row stop the deployment with a one-line reason in the log and the summary (exit 1, the arm stopped)."""

from __future__ import annotations

import json
import sys
import types

import numpy as np
import pytest

from tsrl.cli import main
from tsrl.deploy.backends import FrankaBackend
from tsrl.deploy.contract import read_contract
from tsrl.deploy.loop import read_log_records, replay
from tsrl.exceptions import InvalidAction


class StandInRobot:
    """Records franky.Robot's calls; `move` raises franky's planner error on the calls in `refuse` and
    on every call from `refuse_from` on; a JointMotion's target is the next joint state read (`HOME`
    at first, at rest)."""

    def __init__(self, address, realtime_config):
        self.calls: list[tuple] = [("Robot", address, realtime_config)]
        self.refuse: set[int] = set()
        self.refuse_from: int | None = REFUSE_FROM
        self.moves = 0
        self.relative_dynamics_factor = 1.0
        self.q = list(HOME)
        ROBOTS.append(self)

    @property
    def current_joint_state(self):
        return types.SimpleNamespace(position=list(self.q), velocity=[0.0] * len(self.q))

    def recover_from_errors(self):
        self.calls.append(("recover_from_errors",))
        return True

    def move(self, motion, asynchronous=False):
        self.moves += 1
        if self.moves in self.refuse or (self.refuse_from is not None and self.moves >= self.refuse_from):
            raise RuntimeError("Motion planner failed with error code -111")
        self.calls.append(("move", motion, asynchronous))
        if motion[0] == "JointMotion":
            self.q = list(motion[1])


ROBOTS: list[StandInRobot] = []


class StandInGripper:
    """Records franky.Gripper's calls; a move or grasp reaches its width at once, its future not
    ready while `busy` is set; raises franky's GripperException while `refuse` is set."""

    def __init__(self, address):
        self.calls: list[tuple] = [("Gripper", address)]
        self.width = 0.08
        self.refuse = False
        self.busy = False
        GRIPPERS.append(self)

    def _command(self, call: tuple) -> types.SimpleNamespace:
        if self.refuse:
            raise sys.modules["franky"].GripperException("Command failed: the gripper is not homed")
        self.calls.append(call)
        self.width = call[1]
        return types.SimpleNamespace(wait=lambda timeout=None: not self.busy)  # franky's BoolFuture

    def move_async(self, width, speed):
        return self._command(("move_async", width, speed))

    def grasp_async(self, width, speed, force, epsilon_inner=0.005, epsilon_outer=0.005):
        return self._command(("grasp_async", width, speed, force, epsilon_inner, epsilon_outer))


GRIPPERS: list[StandInGripper] = []
#: The stand-in arm's first joint state, and the move from which every move is refused (None: none).
HOME: list[float] = [0.0] * 7
REFUSE_FROM: int | None = None


@pytest.fixture
def franky(monkeypatch):
    module = types.ModuleType("franky")
    module.Robot = StandInRobot
    module.RealtimeConfig = types.SimpleNamespace(Enforce="Enforce", Ignore="Ignore")
    module.RealtimeException = type("RealtimeException", (Exception,), {})
    module.Exception = type("Exception", (Exception,), {})
    module.JointMotion = lambda q: ("JointMotion", tuple(q))
    module.JointStopMotion = lambda: ("JointStopMotion",)
    module.Gripper = StandInGripper
    module.GripperException = type("GripperException", (Exception,), {})  # not a franky.Exception
    monkeypatch.setitem(sys.modules, "franky", module)
    ROBOTS.clear()
    GRIPPERS.clear()
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
    answers = [backend.send(q) for q in (a, a, a, b, b, c, c, c)]
    # franky's refusal is send's answer (one line), a fault the deploy loop's safety layer handles
    assert answers == [None] * 5 + ["franky: Motion planner failed with error code -111", None, None]
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


@pytest.fixture
def panda_reach(exports):
    return exports("panda_reach", env_id="tsrl/PandaReach-v0")


def deploy_on_stand_in(export, log, monkeypatch, episodes: int = 1, refuse=(), refuse_from=None) -> int:
    """`tsrl deploy` of `export` on the stand-in franky (at the contract's home) with the moves in
    `refuse` refused, and every one from `refuse_from` on."""
    monkeypatch.setattr(sys.modules[__name__], "HOME", list(read_contract(export).robot.home_q))
    monkeypatch.setattr(sys.modules[__name__], "REFUSE_FROM", refuse_from)
    refused = set(refuse)
    original = StandInRobot.__init__

    def init(self, address, realtime_config):
        original(self, address, realtime_config)
        self.refuse = refused

    monkeypatch.setattr(StandInRobot, "__init__", init)
    options = ["--backend", "franka", "--address", "127.0.0.2", "--no-franka-realtime"]
    return main(["deploy", str(export), *options, "--episodes", str(episodes), "--log", str(log)])


def test_a_refused_command_holds_until_the_next_step_and_replays_to_the_same_commands(
    franky, panda_reach, tmp_path, monkeypatch, capsys
):
    log = tmp_path / "deploy.jsonl"
    assert deploy_on_stand_in(panda_reach, log, monkeypatch, refuse={3}) == 0
    out = capsys.readouterr().out
    assert "faults: command_refused x1" in out and "stopped" not in out
    (robot,) = ROBOTS
    assert robot.moves > 3 and robot.calls[-1] == ("move", ("JointStopMotion",), False)
    records = read_log_records(log)
    (episode,) = records.episodes
    assert episode["faults"]["command_refused"] == 1 and episode["stopped"] is None
    refused = [r for r in records.cycles if r.get("refused")]
    assert len(refused) == 1 and refused[0]["step"] == 0 and "command_refused" in refused[0]["faults"]
    ((tick, why),) = refused[0]["refused"]
    assert why == "franky: Motion planner failed with error code -111"
    assert tick < len(refused[0]["servo"]) - 1  # commands followed it in its period: held ones
    again = replay(log)
    assert again.cycles == episode["steps"] and again.max_servo_difference == 0
    # Without the hold the same log's commands come out otherwise: the hold changed what was sent.
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    unheld = tmp_path / "unheld.jsonl"
    unheld.write_text("".join(json.dumps(r | {"refused": []} if "refused" in r else r) + "\n" for r in lines))
    assert replay(unheld).max_servo_difference > 1e-6


def test_five_refused_commands_in_a_row_stop_the_deployment_in_one_line(
    franky, panda_reach, tmp_path, monkeypatch, capsys
):
    log = tmp_path / "deploy.jsonl"
    assert deploy_on_stand_in(panda_reach, log, monkeypatch, episodes=2, refuse_from=10) == 1
    out = capsys.readouterr().out
    reason = (
        "the robot refused 5 commands in a row (the last: franky: Motion planner failed with error code "
        "-111); stopped after 5 in a row"
    )
    (line,) = [line for line in out.splitlines() if line.startswith("stopped by the safety layer")]
    assert line == f"stopped by the safety layer in episode 0: {reason}"
    assert "faults: command_refused x5" in out
    (robot,) = ROBOTS
    assert robot.moves == 9 + 5 + 1  # 9 taken, 5 refused, then JointStopMotion on close (also refused,
    assert robot.calls[-1] == ("recover_from_errors",)  # and recovered from: the arm stopped on its error)
    records = read_log_records(log)
    (episode,) = records.episodes  # the second episode never started
    assert episode["stopped"] == reason and records.ends_early is None
    refused = [tick for r in records.cycles for tick, _ in r.get("refused", [])]
    assert len(refused) == 5
    assert replay(log).max_servo_difference == 0


def test_the_franka_hand_is_driven_through_frankys_gripper(franky):
    backend = FrankaBackend("127.0.0.2", realtime=False, gripper=True)
    backend.connect()
    (robot,), (hand,) = ROBOTS, GRIPPERS
    assert hand.calls == [("Gripper", "127.0.0.2")] and backend.read_state().tool == 0.08
    q = np.zeros(7)
    for width in (0.08, 0.078, 0.02, 0.02, 0.05, 0.08):
        assert backend.send(q, width) is None
    assert hand.calls[1:] == [
        ("move_async", 0.08, 0.1),  # 0.078 is within 5 mm of it: held
        ("grasp_async", 0.02, 0.1, 70.0, 0.08, 0.08),  # closing: onto what lies between the fingers
        ("move_async", 0.05, 0.1),  # opening
        ("move_async", 0.08, 0.1),
    ]
    assert backend.read_state().tool == 0.08 and robot.moves == 1  # the joint target was held
    for bad in (np.nan, -0.01, 0.09, np.inf):
        with pytest.raises(InvalidAction, match="gripper width .* not sent"):
            backend.send(q + 0.1, bad)
    assert len(hand.calls) == 5 and robot.moves == 1  # neither the width nor the joints were sent
    hand.refuse = True
    assert backend.send(q, 0.03) == "franky gripper: Command failed: the gripper is not homed"
    hand.refuse = False
    assert backend.send(q, 0.03) is None and hand.calls[-1][:2] == ("grasp_async", 0.03)
    hand.busy = True  # one hand command at a time: a new width waits until the last one is done
    assert backend.send(q, 0.06) is None and backend.send(q, 0.07) is None and len(hand.calls) == 6
    hand.busy = False
    assert backend.send(q, 0.07) is None and hand.calls[-1] == ("move_async", 0.07, 0.1)
    backend.close()
    assert hand.calls[-1] == ("move_async", 0.07, 0.1)  # the hand is left as it is (no call on close)
    plain = FrankaBackend("127.0.0.2", realtime=False)
    plain.connect()
    assert len(GRIPPERS) == 1 and plain.read_state().tool is None
    assert plain.send(q, 0.02) is None and len(GRIPPERS[0].calls) == 7  # no hand: the width is not sent


def test_tsrl_deploy_drives_the_hand_for_a_gripper_task_only(franky, exports, panda_reach):
    from tsrl.deploy.backends import check_backend, make_backend

    gripper_task = exports("panda_pick_place_gripper", env_id="tsrl/PandaPickPlaceGripper-v0", obs="")
    for export, gripper in ((gripper_task, True), (panda_reach, False)):
        backend = make_backend("franka", export, "127.0.0.2", {}, franka_realtime=False)
        assert isinstance(backend, FrankaBackend) and backend.gripper is gripper
        check_backend(backend, read_contract(export))  # the hand's arm has the Panda's joints
