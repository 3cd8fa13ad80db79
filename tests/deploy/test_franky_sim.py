"""FrankaBackend against franky-sim (a simulator of the Franka arm's network protocol, on 127.0.0.2 in a
private network namespace: tests/deploy/franky_sim_run.py): the conformance test of test_backends.py
with the realtime check relaxed, and libfranka's default realtime check refused in one line naming
--no-franka-realtime. Skipped without franky-control, franky-sim, or the right to `unshare -n`."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

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


def test_the_franka_backend_passes_the_conformance_test_on_franky_sim(tmp_path):
    log = tmp_path / "franky-sim.log"
    run = subprocess.run(
        ["unshare", "-n", sys.executable, str(RUNNER), str(log)],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
    )
    sim = log.read_text() if log.exists() else ""
    assert run.returncode == 0, f"{run.stdout}\n{run.stderr}\nfranky-sim:\n{sim}"
    assert "conformance passed" in run.stdout
    if Path("/sys/kernel/realtime").exists() and Path("/sys/kernel/realtime").read_text().strip() == "1":
        return
    (line,) = [line for line in run.stdout.splitlines() if line.startswith("realtime required: ")]
    assert "libfranka refuses to run without a realtime kernel" in line and "--no-franka-realtime" in line
