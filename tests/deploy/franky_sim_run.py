"""The parts of tests/deploy/test_franky_sim.py that run inside the simulator's private network
namespace (started with `unshare`, joined with `nsenter`):

    serve HOST                  bring the loopback up, then become franky-sim on HOST (port 1337)
    conformance HOST            the RobotBackend conformance test on FrankaBackend (realtime relaxed)
    deploy HOST EXPORT LOG      `tsrl deploy` of one episode of EXPORT with --no-franka-realtime
    realtime HOST               one connection with libfranka's default realtime check
    gripper HOST                the Franka Hand through FrankaBackend: to 70 mm, 20 mm (a grasp), 70 mm

Each prints what it found; exit 0 when it ran through (a failed check exits 1 with its traceback)."""

from __future__ import annotations

import fcntl
import os
import socket
import struct
import sys
from pathlib import Path

SIOCGIFFLAGS, SIOCSIFFLAGS, IFF_UP = 0x8913, 0x8914, 0x1


def loopback_up() -> None:
    """Brings `lo` up (a new network namespace starts with it down), as `ip link set lo up` does."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        request = struct.pack("16sh22x", b"lo", 0)  # struct ifreq: the name, then ifr_flags
        flags = struct.unpack("16sh22x", fcntl.ioctl(s, SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(s, SIOCSIFFLAGS, struct.pack("16sh22x", b"lo", flags | IFF_UP))


def serve(host: str) -> None:
    """Replaces this process by franky-sim (same process id) on `host`, with the loopback up."""
    loopback_up()
    sim = str(Path(sys.executable).parent / "franky-sim")
    os.execv(sim, [sim, "--simulator", "mujoco", "--hostname", host])


def conformance(host: str) -> None:
    sys.path.insert(0, str(Path(__file__).parent))
    from test_backends import conformance as check

    from tsrl.deploy.backends import FrankaBackend

    backend = FrankaBackend(host, realtime=False)
    check(backend)
    print(f"conformance passed; franky refused {backend.failed_commands} commands")


def deploy(host: str, export: str, log: str) -> None:
    from tsrl.cli import main

    options = ["--backend", "franka", "--address", host, "--no-franka-realtime", "--episodes", "1"]
    code = main(["deploy", export, *options, "--speed-scale", "0.25", "--log", log])
    print(f"deploy exit {code}")


def realtime(host: str) -> None:
    from tsrl.deploy.backends import BackendError, FrankaBackend

    backend = FrankaBackend(host)
    try:
        backend.connect()
    except BackendError as err:
        print(f"realtime required: {err}")
        return
    backend.close()
    print("realtime: connected")


def gripper(host: str) -> None:
    import time

    from tsrl.deploy.backends import FrankaBackend

    backend = FrankaBackend(host, realtime=False, gripper=True)
    backend.connect()
    try:
        state = backend.read_state()
        print(f"gripper width {state.tool:.4f}")
        for target in (0.07, 0.02, 0.07):  # a move, a grasp onto nothing, a move
            answers = set()
            deadline = time.monotonic() + 30.0  # a bound on the simulated hand's travel, not its speed
            width = backend.read_state().tool
            while abs(width - target) > 0.003 and time.monotonic() < deadline:
                answers.add(backend.send(state.q, target))  # every tick, as the deploy loop sends it
                backend.wait()
                width = backend.read_state().tool
            print(f"gripper to {target}: answers {sorted(map(repr, answers))}, width {width:.6f}")
    finally:
        backend.close()


if __name__ == "__main__":
    command, *args = sys.argv[1:]
    commands = {"serve": serve, "conformance": conformance, "deploy": deploy, "realtime": realtime}
    (commands | {"gripper": gripper})[command](*args)
