"""Cost of evaluating each observation preset (values and Jacobians) next to one control period of physics.

One control period is 20 `mj_step` calls on the reach scene (25 Hz control, 2 ms physics step),
measured in the same run. Target: fs2 costs at most 25% of it.

    python benchmarks/taskmaps.py [--evals 2000] [--repeats 7] [--save [NAME]]

--save writes the rows to docs/results/benchmarks/taskmaps/ (benchmarks/record.py); `table` renders
docs/taskmaps.md's table from them.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

SUBSTEPS = 20  # 40 ms control period / 2 ms physics step
#: The reach presets (Table I); the pick-and-place presets need a box in the scene.
PRESETS = ("baseline", "simple", "fs0", "fs1", "fs2")


def best_time_us(fn: Callable[[], None], n: int, repeats: int) -> float:
    """Microseconds per call of fn, the best of `repeats` runs of n calls (least disturbed by other load)."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, time.perf_counter() - start)
    return best / n * 1e6


def measure(evals: int, repeats: int) -> list[dict[str, Any]]:
    """One row per observation preset (name, dim, us per evaluation) and a first row "physics"
    (us per control period, dim 0)."""
    import mujoco

    from tsrl.assets import load_model
    from tsrl.envs import parse_observation
    from tsrl.kinematics import forward_kinematics, random_configurations

    model = load_model("reach")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)

    def control_period() -> None:
        for _ in range(SUBSTEPS):
            mujoco.mj_step(model, data)

    rows: list[dict[str, Any]] = [
        {"preset": "physics", "dim": 0, "us": best_time_us(control_period, max(evals // 10, 50), repeats)}
    ]
    rng = np.random.default_rng(0)
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    for name in PRESETS:
        stack = parse_observation(name, model)
        eval_us = best_time_us(lambda stack=stack: stack(model, data), evals, repeats)
        rows.append({"preset": name, "dim": stack.dim, "us": eval_us})
    return rows


def render(rows: list[dict[str, Any]]) -> list[str]:
    """docs/taskmaps.md's table (markdown lines) from `measure`'s rows (or their CSV strings)."""
    physics = float(rows[0]["us"])
    lines = [
        f"Physics: {physics:.1f} us per control period ({SUBSTEPS} x `mj_step`, reach scene).",
        "",
        "| preset | dim | us per evaluation (y, J) | ratio to physics |",
        "| --- | ---: | ---: | ---: |",
    ]
    for r in rows[1:]:
        lines.append(
            f"| {r['preset']} | {r['dim']} | {float(r['us']):.1f} | {float(r['us']) / physics:.1%} |"
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evals", type=int, default=2000, help="evaluations per timing run")
    parser.add_argument("--repeats", type=int, default=7, help="timing runs; the best is reported")
    add_save_argument(parser, "taskmaps")
    args = parser.parse_args()
    with Measurement(args.save, __file__, "table", "docs/taskmaps.md") as out:
        rows = measure(args.evals, args.repeats)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))


if __name__ == "__main__":
    main()
