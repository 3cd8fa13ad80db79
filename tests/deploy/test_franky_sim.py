"""FrankaBackend against franky-sim (a simulator of the Franka arm's network protocol, on 127.0.0.2 in a
private network namespace: tests/deploy/franky_sim_run.py): the conformance test of test_backends.py
with the realtime check relaxed, a one-episode `tsrl deploy` of a Panda reach export, and libfranka's default realtime check refused in one line naming
--no-franka-realtime. Skipped without franky-control, franky-sim, or the right to `unshare -n`."""

from __future__ import annotations

import importlib.util
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tsrl.deploy.contract import read_contract
from tsrl.deploy.loop import read_log

RUNNER = Path(__file__).with_name("franky_sim_run.py")


def _can_unshare() -> bool:
    try:
        return (
            subprocess.run(["unshare", "-n", "true"], check=False, capture_output=True, timeout=10).returncode
            == 0
        )
    except (OSError, subprocess.TimeoutExpired):
        return False


pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("franky") is None
    or importlib.util.find_spec("franky_sim") is None
    or not _can_unshare(),
    reason="needs franky-control >= 1.1.4, franky-sim 1.0.4 and `unshare -n` (a private network namespace)",
)


def test_the_franka_backend_passes_the_conformance_test_and_deploys_on_franky_sim(exports, tmp_path):
    export = exports("panda_reach", env_id="tsrl/PandaReach-v0")
    log, deploy_log = tmp_path / "franky-sim.log", tmp_path / "deploy.jsonl"
    command = ["unshare", "-n", sys.executable, str(RUNNER), str(log), str(export), str(deploy_log)]
    with subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True
    ) as run:
        try:
            out = run.communicate(timeout=240)[0].decode()
        except subprocess.TimeoutExpired:
            os.killpg(run.pid, signal.SIGKILL)  # the runner and the simulator it started
            out = run.communicate()[0].decode() + "\n(timed out after 240 s)"
    sim = log.read_text() if log.exists() else ""
    assert run.returncode == 0, f"{out}\nfranky-sim:\n{sim}"
    assert "conformance passed" in out and "deploy exit 0" in out
    assert "franka: realtime kernel not required (--no-franka-realtime" in out
    _, records, (episode,) = read_log(deploy_log)
    cycles = [r for r in records if r["type"] == "cycle"]
    assert len(cycles) == 50 and episode["timing"]["steps"] == 50
    q = np.array([r["q"] for r in cycles])
    limits = np.array(read_contract(export)["robot"]["joint_limits"])
    assert np.abs(q - q[0]).max() > 0.005  # the simulated arm followed the commands
    assert (q >= limits[:, 0]).all() and (q <= limits[:, 1]).all()
    if Path("/sys/kernel/realtime").exists() and Path("/sys/kernel/realtime").read_text().strip() == "1":
        return
    (line,) = [line for line in out.splitlines() if line.startswith("realtime required: ")]
    assert "libfranka refuses to run without a realtime kernel" in line and "--no-franka-realtime" in line
