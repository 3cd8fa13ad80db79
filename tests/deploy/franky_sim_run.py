"""Runs the RobotBackend conformance test (tests/deploy/test_backends.py) on FrankaBackend against
franky-sim, a simulator of the Franka arm's network protocol; run inside a private network namespace
(`unshare -n`, tests/deploy/test_franky_sim.py), where it brings the loopback up, starts the simulator
on 127.0.0.2 (port 1337), waits for it, runs the test (then connects once more with libfranka's
default realtime check, which an ordinary kernel fails) and stops the simulator by its process id.
With an export folder and a log path after the simulator's log file, `tsrl deploy` runs one episode
of the export on it too. Exit 0 when the test passes; the simulator's output follows on failure."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import traceback
from pathlib import Path

HOST, PORT = "127.0.0.2", 1337
STARTUP_S = 60.0


def wait_for_port(process: subprocess.Popen[bytes], timeout: float) -> None:
    """Returns once the simulator accepts connections; raises if it exits or `timeout` [s] passes."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"franky-sim exited with {process.returncode} before it listened")
        try:
            with socket.create_connection((HOST, PORT), timeout=0.5):
                return
        except OSError:
            time.sleep(0.2)
    raise RuntimeError(f"franky-sim did not listen on {HOST}:{PORT} within {timeout} s")


def _realtime_kernel() -> bool:
    path = Path("/sys/kernel/realtime")
    return path.exists() and path.read_text().strip() == "1"


def main() -> int:
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    sim_bin = Path(sys.executable).parent / "franky-sim"
    log = Path(sys.argv[1])
    with open(log, "wb") as out:
        sim = subprocess.Popen(
            [str(sim_bin), "--simulator", "mujoco", "--hostname", HOST], stdout=out, stderr=subprocess.STDOUT
        )
        try:
            wait_for_port(sim, STARTUP_S)
            sys.path.insert(0, str(Path(__file__).parent))
            from test_backends import conformance

            from tsrl.deploy.backends import BackendError, FrankaBackend

            backend = FrankaBackend(HOST, realtime=False)
            conformance(backend)
            print(f"conformance passed; franky refused {backend.failed_commands} commands")
            if len(sys.argv) > 3:  # a short deploy of an exported policy
                from tsrl.cli import main as tsrl

                deploy = [sys.argv[2], "--backend", "franka", "--address", HOST, "--no-franka-realtime"]
                code = tsrl(
                    ["deploy", *deploy, "--episodes", "1", "--speed-scale", "0.25", "--log", sys.argv[3]]
                )
                print(f"deploy exit {code}")
            if not _realtime_kernel():  # libfranka's default refuses it (last: it leaves the server busy)
                try:
                    FrankaBackend(HOST).connect()
                except BackendError as err:
                    print(f"realtime required: {err}")
            return 0
        except Exception:  # noqa: BLE001  (the report is the test's)
            traceback.print_exc()
            return 1
        finally:
            sim.terminate()
            try:
                sim.wait(timeout=10)
            except subprocess.TimeoutExpired:
                sim.kill()
                sim.wait()


if __name__ == "__main__":
    sys.exit(main())
