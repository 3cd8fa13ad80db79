"""Environment step cost in CPU instructions (valgrind's callgrind): a cross-check of env_step.py that
the machine's changing speed cannot move.

Counts the instructions of N and 4N random-action steps of tsrl/UR5eReach-v0 (fs2, taskspace) and of
Gymnasium-Robotics FetchReach-v4, each in its own process under callgrind, and reports the
difference / 3N: instructions per step, start-up and resets excluded. Instructions are not time
(memory stalls and branch misses are not counted), so env_step.py stays the measure of the target;
this one shows what a code change did. OpenBLAS runs single-threaded here: its idle helper threads
would otherwise add their spinning to the count.

    python benchmarks/env_step_instructions.py [--steps 100] [--save [NAME]]  # needs valgrind; minutes

--save writes each process's count (env, steps, instructions) to docs/results/benchmarks/NAME/
(default env-step-instructions) with meta.json (benchmarks/record.py); `table` renders docs/envs.md's
table from them.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows


def run_steps(name: str, steps: int) -> None:
    """Resets env_step.ENVS[name] once and takes `steps` random-action steps (resetting at episode ends)."""
    import numpy as np
    from env_step import make_env

    env = make_env(name)
    actions = (
        np.random.default_rng(0).uniform(-1, 1, (steps, *(env.action_space.shape or ()))).astype(np.float32)
    )
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


def measure(steps: int) -> list[dict[str, Any]]:
    """One row per process: env (env_step.ENVS' name), steps (N or 4N), instructions."""
    from env_step import ENVS

    rows = []
    for name in ENVS:
        for n in (steps, 4 * steps):
            rows.append({"env": name, "steps": n, "instructions": instructions(name, n)})
        print(f"measured {name}", file=sys.stderr, flush=True)
    return rows


def render(rows: list[dict[str, Any]]) -> list[str]:
    """docs/envs.md's instruction table (markdown lines) from `measure`'s rows (or their CSV strings):
    per environment, (count at 4N - count at N) / 3N."""
    per_step, steps = {}, 0
    for name in dict.fromkeys(r["env"] for r in rows):
        counts = sorted((int(r["steps"]), int(r["instructions"])) for r in rows if r["env"] == name)
        (n, short), (n4, long) = counts
        per_step[name], steps = (long - short) / (n4 - n), n4 - n
    lines = [
        f"Instructions per step (callgrind, {steps} random-action steps, start-up excluded):",
        "",
        "| environment | instructions per step |",
        "| --- | ---: |",
    ]
    lines += [f"| {name} | {count:,.0f} |" for name, count in per_step.items()]
    ours, fetch = per_step.values()
    return lines + ["", f"Ratio FetchReach-v4 / tsrl: {fetch / ours:.2f}x (instructions per step)."]


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="N: the processes take N and 4N steps")
    parser.add_argument("--child", nargs=2, metavar=("ENV", "STEPS"), help=argparse.SUPPRESS)
    add_save_argument(parser, "env-step-instructions")
    args = parser.parse_args()
    if args.child:
        run_steps(args.child[0], int(args.child[1]))
        return
    if shutil.which("valgrind") is None:
        sys.exit("valgrind is not installed (Debian: apt-get install valgrind)")
    with Measurement(args.save, __file__, "table", "docs/envs.md") as out:
        rows = measure(args.steps)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n" + "\n".join(render(rows)))


if __name__ == "__main__":
    main()
