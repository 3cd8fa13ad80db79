"""Environment step cost in CPU instructions (valgrind's callgrind): a cross-check of env_step.py that
the machine's changing speed cannot move.

Counts the instructions of N and 4N random-action steps of tsrl/UR5eReach-v0 (fs2, taskspace) and of
Gymnasium-Robotics FetchReach-v4, each in its own process under callgrind, and reports the
difference / 3N: instructions per step, start-up and resets excluded. Instructions are not time
(memory stalls and branch misses are not counted), so env_step.py stays the measure of the target;
this one shows what a code change did. OpenBLAS runs single-threaded here: its idle helper threads
would otherwise add their spinning to the count.

    python benchmarks/env_step_instructions.py [--steps 100]   # needs valgrind; a few minutes
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path


def run_steps(name: str, steps: int) -> None:
    """Resets env_step.ENVS[name] once and takes `steps` random-action steps (resetting at episode ends)."""
    import numpy as np
    from env_step import make_env

    env = make_env(name)
    actions = np.random.default_rng(0).uniform(-1, 1, (steps, *env.action_space.shape)).astype(np.float32)
    env.reset(seed=0)
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    env.close()


def instructions(name: str, steps: int) -> int:
    """Instructions callgrind counts for a whole child process that takes `steps` steps."""
    env = os.environ | {"OPENBLAS_NUM_THREADS": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    cmd = ["valgrind", "--tool=callgrind", "--callgrind-out-file=/dev/null"]
    cmd += [sys.executable, __file__, "--child", name, str(steps)]
    out = subprocess.run(cmd, env=env, cwd=Path(__file__).parent, capture_output=True, text=True, check=True)
    match = re.search(r"I\s+refs:\s*([\d,]+)", out.stderr)
    if match is None:
        raise RuntimeError(f"no instruction count in callgrind's output:\n{out.stderr[-2000:]}")
    return int(match.group(1).replace(",", ""))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="N: the processes take N and 4N steps")
    parser.add_argument("--child", nargs=2, metavar=("ENV", "STEPS"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        run_steps(args.child[0], int(args.child[1]))
        return
    if shutil.which("valgrind") is None:
        sys.exit("valgrind is not installed (Debian: apt-get install valgrind)")
    n = args.steps
    from env_step import ENVS

    per_step = {}
    for name in ENVS:
        per_step[name] = (instructions(name, 4 * n) - instructions(name, n)) / (3 * n)
        print(f"measured {name}", file=sys.stderr, flush=True)
    print(f"\nInstructions per step (callgrind, {3 * n} random-action steps, start-up excluded):\n")
    print("| environment | instructions per step |\n| --- | ---: |")
    for name, count in per_step.items():
        print(f"| {name} | {count:,.0f} |")
    ours, fetch = per_step.values()
    print(f"\nratio FetchReach-v4 / tsrl: {fetch / ours:.2f}x (instructions per step)")


if __name__ == "__main__":
    main()
