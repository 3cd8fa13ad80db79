"""Runs the `tsrl` command line in a subprocess, as a user would (`python -m tsrl.cli`)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

#: Seconds-long training: 100 random steps, evaluation and checkpoint every 100 env steps (2 episodes).
TINY = [
    "--total-timesteps", "200", "--learning-starts", "100", "--gradient-steps", "10", "--batch-size", "64",
    "--eval-freq", "100", "--eval-episodes", "2", "--checkpoint-freq", "100", "--no-progress",
]  # fmt: skip
#: The run folder TINY's defaults train into.
RUN_NAME = "tsrl-UR5eReach-v0__baseline__taskspace__ddpg__s0"  # the reach's own observation
#: The checkout's root: experiment definitions under experiments/ are found from here.
REPO = Path(__file__).resolve().parents[1]


def run_tsrl(*args: str, cwd: Path = REPO, timeout: float = 180) -> subprocess.CompletedProcess:
    """`tsrl *args` with its exit code, stdout and stderr (text); never raises on a non-zero exit."""
    return subprocess.run(
        [sys.executable, "-m", "tsrl.cli", *args],
        check=False,
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout,
    )


#: `python -m tsrl.cli` with Ctrl-C (SIGINT) handled as by default: a process started in the
#: background by a non-interactive shell (`make test &`, nohup) ignores SIGINT, its children inherit
#: that and Python then leaves it ignored, so the Ctrl-C tests would send a signal no one receives.
_WITH_CTRL_C = (
    "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
    "sys.argv[0] = 'tsrl'; runpy.run_module('tsrl.cli', run_name='__main__', alter_sys=True)"
)
TSRL_WITH_CTRL_C = [sys.executable, "-c", _WITH_CTRL_C]
