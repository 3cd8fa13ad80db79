"""FrankaBackend against franky-sim, a simulator of the Franka arm's network protocol, run on 127.0.0.2
in a private network namespace of its own (the `franky_sim` fixture; the code that runs inside is
tests/deploy/franky_sim_run.py): the conformance test of test_backends.py with the realtime check
relaxed, a one-episode `tsrl deploy` of a Panda reach export whose log is complete and replays to the
same commands, libfranka's default realtime check refused in one line naming --no-franka-realtime, and
the Franka Hand (franky-sim simulates it) opened, closed by a grasp and opened through FrankaBackend.
Nothing here depends on how fast the machine is: the checks are on poses, counts and the log.
Skipped, with the reason, without franky-control and franky-sim (the dev extra) or a network
namespace (`unshare -n` as root, else `unshare -rn`, a user namespace, and `nsenter` to join it)."""

from __future__ import annotations

import functools
import importlib.util
import math
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from tsrl.deploy.contract import read_contract
from tsrl.deploy.loop import read_log_records, replay

RUNNER = Path(__file__).with_name("franky_sim_run.py")
HOST, PORT = "127.0.0.2", 1337
STARTUP_S = 120.0  # a bound on waiting for the simulator to listen, not a check of its speed
RUN_S = 300.0  # the same for one runner command

#: (unshare's options, nsenter's options): a network namespace as root; a user namespace otherwise.
NAMESPACES = ((["-n"], ["--net"]), (["-rn"], ["--user", "--net", "--preserve-credentials"]))
PACKAGES = (("franky-control", "franky"), ("franky-sim", "franky_sim"))  # (distribution, module)


def _last_line(text: str) -> str:
    return text.strip().splitlines()[-1] if text.strip() else "no message"


@functools.cache
def namespace_options() -> tuple[list[str], list[str]] | str:
    """The first of NAMESPACES that can be made and joined here, or why none can (one line)."""
    missing = [tool for tool in ("unshare", "nsenter") if shutil.which(tool) is None]
    if missing:
        return f"needs util-linux's {' and '.join(missing)} (a private network namespace)"
    refused = []
    for unshare, nsenter in NAMESPACES:
        holder = subprocess.Popen(  # says "ready" once inside the new namespace, then waits there
            ["unshare", *unshare, "sh", "-c", "echo ready && exec sleep 60"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        try:
            assert holder.stdout is not None and holder.stderr is not None
            if holder.stdout.readline() != b"ready\n":
                refused.append(f"`unshare {unshare[0]}`: {_last_line(holder.stderr.read().decode())}")
                continue
            join = subprocess.run(
                ["nsenter", "--target", str(holder.pid), *nsenter, "true"],
                check=False,
                capture_output=True,
                timeout=30,
            )
            if join.returncode == 0:
                return unshare, nsenter
            refused.append(f"`nsenter {' '.join(nsenter)}`: {_last_line(join.stderr.decode())}")
        finally:
            if holder.poll() is None:
                os.kill(holder.pid, signal.SIGKILL)
            holder.communicate()
    return "needs a private network namespace; refused here: " + "; ".join(refused)


def missing_packages() -> str | None:
    """Why the simulator or franky cannot be imported here, or None."""
    missing = [name for name, module in PACKAGES if importlib.util.find_spec(module) is None]
    return f"needs {' and '.join(missing)} (pip install -e '.[dev]')" if missing else None


def _listening(pid: int) -> bool:
    """Whether a socket of process `pid`'s own network namespace listens on HOST:PORT (/proc/PID/net/tcp)."""
    try:
        if os.readlink(f"/proc/{pid}/ns/net") == os.readlink("/proc/self/ns/net"):
            return False  # not in its namespace yet
        rows = Path(f"/proc/{pid}/net/tcp").read_text().splitlines()[1:]
    except OSError:
        return False
    for row in rows:
        local, state = row.split()[1], row.split()[3]
        address, port = local.split(":")
        ip = socket.inet_ntoa(struct.pack("=I", int(address, 16)))
        if state == "0A" and ip == HOST and int(port, 16) == PORT:  # 0A: LISTEN
            return True
    return False


@dataclass
class FrankySim:
    """A running franky-sim: its process id, how to join its namespace, its output."""

    pid: int
    nsenter: list[str]
    log: Path

    def run(self, *args: str) -> str:
        """franky_sim_run.py ARGS inside the simulator's namespace; its output, or a failed test."""
        command = ["nsenter", "--target", str(self.pid), *self.nsenter, sys.executable, str(RUNNER), *args]
        try:
            done = subprocess.run(command, check=False, capture_output=True, timeout=RUN_S)
        except subprocess.TimeoutExpired as err:
            pytest.fail(f"{args[0]} did not end within {RUN_S} s\n{err.stdout!r}\n{err.stderr!r}")
        out = done.stdout.decode() + done.stderr.decode()
        assert done.returncode == 0, f"{out}\nfranky-sim:\n{self.log.read_text()}"
        return out


@pytest.fixture
def franky_sim(tmp_path: Path) -> Iterator[FrankySim]:
    """franky-sim on HOST in a network namespace of its own, listening; stopped by its process id."""
    reason = missing_packages()
    options = namespace_options() if reason is None else reason
    if isinstance(options, str):
        pytest.skip(options)
    unshare, nsenter = options
    log = tmp_path / "franky-sim.log"
    with open(log, "wb") as out:  # unshare execs the runner, which execs franky-sim: one process id
        sim = subprocess.Popen(
            ["unshare", *unshare, sys.executable, str(RUNNER), "serve", HOST],
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    try:
        deadline = time.monotonic() + STARTUP_S
        while not _listening(sim.pid):
            if sim.poll() is not None or time.monotonic() > deadline:
                pytest.fail(f"franky-sim did not listen on {HOST}:{PORT}:\n{log.read_text()}")
            time.sleep(0.2)
        yield FrankySim(sim.pid, nsenter, log)
    finally:
        if sim.poll() is None:
            os.kill(sim.pid, signal.SIGTERM)
            try:
                sim.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.kill(sim.pid, signal.SIGKILL)
                sim.wait()


def test_the_franka_backend_passes_the_conformance_test(franky_sim):
    out = franky_sim.run("conformance", HOST)
    assert "conformance passed" in out


def test_a_deploy_on_franky_sim_logs_every_step_and_replays_to_the_same_commands(
    franky_sim, exports, tmp_path
):
    export = exports("panda_reach", env_id="tsrl/PandaReach-v0")
    log = tmp_path / "deploy.jsonl"
    out = franky_sim.run("deploy", HOST, str(export), str(log))
    assert "deploy exit 0" in out
    assert "franka: realtime kernel not required (--no-franka-realtime" in out

    records = read_log_records(log)
    assert records.ends_early is None and records.header["backend"] == "franka"
    (episode,) = records.episodes
    cycles = [r for r in records.cycles if r["type"] == "cycle"]
    assert [r["step"] for r in cycles] == list(range(50)) and episode["steps"] == 50
    contract = read_contract(export)
    limits = np.array(contract.robot.joint_limits)
    ticks = round(contract.task.control_period_s / 0.01)  # FrankaBackend's 10 ms servo period
    assert all(len(r["servo"]) == len(r["servo_t"]) == ticks for r in cycles)
    q = np.array([r["q"] for r in cycles])
    servo = np.concatenate([np.array(r["servo"], np.float64) for r in cycles])
    assert np.isfinite(q).all() and np.isfinite(servo).all()
    assert all(math.isfinite(t) for r in cycles for t in r["servo_t"])
    assert np.abs(q - q[0]).max() > 0.005  # the simulated arm followed the commands
    for joints in (q, servo):  # within the contract's joint limits
        assert (joints >= limits[:, 0]).all() and (joints <= limits[:, 1]).all()
    # Each servo command moves a joint by at most its speed limit times the 10 ms servo period.
    step = np.array(contract.robot.max_joint_speed) * 0.01
    assert (np.abs(np.diff(servo, axis=0)) <= step + 1e-12).all()
    # The log is the deploy's whole record: recomputed from it, every command comes out the same.
    again = replay(log)
    assert again.cycles == 50 and again.ends_early is None
    assert again.max_target_difference == 0 and again.max_servo_difference == 0


def test_libfrankas_realtime_check_is_refused_in_one_line_naming_the_option(franky_sim):
    realtime = Path("/sys/kernel/realtime")
    if realtime.exists() and realtime.read_text().strip() == "1":
        pytest.skip("a realtime kernel: libfranka's check passes here")
    out = franky_sim.run("realtime", HOST)
    (line,) = [line for line in out.splitlines() if line.startswith("realtime required: ")]
    assert "libfranka refuses to run without a realtime kernel" in line and "--no-franka-realtime" in line


def test_the_franka_hand_closes_and_opens_through_frankys_gripper(franky_sim):
    out = franky_sim.run("gripper", HOST)
    reached = []
    for line in out.splitlines():
        if line.startswith("gripper to "):
            target, rest = line.removeprefix("gripper to ").split(": ", 1)
            assert "answers ['None']" in rest, line
            reached.append((float(target), float(rest.rsplit("width ", 1)[1])))
    assert [target for target, _ in reached] == [0.07, 0.02, 0.07], out
    assert all(abs(width - target) <= 0.003 + 1e-6 for target, width in reached), out
