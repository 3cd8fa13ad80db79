"""How many sampled goals do the scripted solvers of the built-in tasks reach? A table of success rates
over N seeded episodes per task (seeds 0..N-1) for every task of the solver registry
(`tsrl.envs.solvers.SOLVERS`, both robots), in the task's own action, and for the obstacle tasks the
episodes in which the obstacle is in contact at reset (before any action), and those in which the robot
touched it (a penalised step): at all, already on the first step, and still on the last (resting at the
goal).

The tests (`tests/envs/test_tasks.py`, `tests/envs/test_pick_place_scripted.py`) assert at least 99 (95
for pick-and-place) of 100; this prints the rate on more goals.

    python benchmarks/solvers.py [--episodes 1000] [--tasks UR5ePoseReach-v0 ...] [--save [NAME]]

--save writes one row per episode (task, solver, seed, success, steps, and the obstacle columns) to
docs/results/benchmarks/solvers/ (benchmarks/record.py); `table` renders docs/tasks.md's table from
them.
"""

from __future__ import annotations

import argparse
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

#: The obstacle columns of a row: in contact at reset; a penalised step at all, on the first, on the last.
CONTACT = ("contact_at_reset", "touched", "touched_first_step", "touched_last_step")
#: Failed seeds a table row lists before "...".
SHOWN_FAILURES = 8


def episodes(name: str, n: int) -> Iterator[dict[str, Any]]:
    """One row per seeded episode (seeds 0..n-1) of task `name`'s solver: success (0/1), env steps, and
    for an obstacle task the CONTACT columns (0/1; empty strings for other tasks)."""
    import gymnasium as gym
    import mujoco

    import tsrl  # noqa: F401  (registers the environments)
    from tsrl.envs.solvers import SOLVERS

    env_id = f"tsrl/{name}"
    with warnings.catch_warnings():  # v0 is measured on purpose: no out-of-date warning
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id)
    base: Any = env.unwrapped  # a tsrl TaskEnv
    obstacle = base.model.geom(base.task.obstacle.geom).id if base.task.obstacle else None
    solver_class = SOLVERS[name]
    solver = solver_class(base)
    try:
        for seed in range(n):
            obs, _ = env.reset(seed=seed)
            at_reset = False
            if obstacle is not None:
                mujoco.mj_collision(base.model, base.data)
                at_reset = any(obstacle in c.geom for c in base.data.contact[: base.data.ncon])
            solver.reset(obs)
            truncated, penalised = False, []
            while not truncated:
                obs, _, _, truncated, info = env.step(solver.act(obs))
                penalised.append(info.get("penalty", 0.0) != 0.0)
            row: dict[str, Any] = {
                "task": env_id,
                "solver": solver_class.__name__,
                "seed": seed,
                "success": int(bool(info["is_success"])),
                "steps": len(penalised),
            }
            flags = [at_reset, any(penalised), penalised[0], penalised[-1]]
            for column, flag in zip(CONTACT, flags, strict=True):
                row[column] = int(flag) if obstacle is not None else ""
            yield row
    finally:
        env.close()


def render(rows: list[dict[str, Any]]) -> list[str]:
    """docs/tasks.md's table (markdown lines) from `episodes`' rows (or their CSV strings), one line per
    task in the rows' order."""
    lines = [
        (
            "| task | solver | success | episodes with the obstacle in contact at reset "
            "| episodes the solver touches it: at all / on step 1 / on the last step | failed seeds |"
        ),
        "| --- | --- | ---: | ---: | ---: | --- |",
    ]
    for task in dict.fromkeys(r["task"] for r in rows):
        mine = [r for r in rows if r["task"] == task]
        wins = sum(int(r["success"]) for r in mine)
        failed = [str(r["seed"]) for r in mine if not int(r["success"])]
        shown = ", ".join(failed[:SHOWN_FAILURES]) + (" ..." if len(failed) > SHOWN_FAILURES else "")
        if mine[0]["contact_at_reset"] == "":
            reset, touched = "–", "–"
        else:
            counts = [sum(int(r[c]) for r in mine) for c in CONTACT]
            reset, touched = str(counts[0]), " / ".join(map(str, counts[1:]))
        lines.append(
            f"| `{task}` | {mine[0]['solver']} | {wins}/{len(mine)} | {reset} | {touched} | {shown or 'none'} |"
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    from tsrl.envs.solvers import SOLVERS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=1000, help="seeded episodes per task (seeds 0..N-1)")
    parser.add_argument(
        "--tasks", nargs="+", choices=list(SOLVERS), default=list(SOLVERS), help="built-in tasks"
    )
    add_save_argument(parser, "solvers")
    args = parser.parse_args()
    with Measurement(args.save, __file__, "table", "docs/tasks.md") as out:
        rows: list[dict[str, Any]] = []
        for name in args.tasks:
            rows.extend(episodes(name, args.episodes))
            print(render(rows)[-1], flush=True)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))
    print(f"\n(numpy {np.__version__})")


if __name__ == "__main__":
    main()
