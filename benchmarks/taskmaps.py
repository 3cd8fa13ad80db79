"""Cost of evaluating each observation preset (values and Jacobians) next to one control period of physics.

One control period is 20 `mj_step` calls on the reach scene (25 Hz control, 2 ms physics step),
measured in the same run. Target: fs2 costs at most 25% of it.

    python benchmarks/taskmaps.py [--evals 2000] [--repeats 7]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import mujoco
import numpy as np

from tsrl.assets import load_model
from tsrl.envs import OBS_PRESETS, parse_observation
from tsrl.kinematics import forward_kinematics, random_configurations

SUBSTEPS = 20  # 40 ms control period / 2 ms physics step


def best_time_us(fn: Callable[[], None], n: int, repeats: int) -> float:
    """Microseconds per call of fn, the best of `repeats` runs of n calls (least disturbed by other load)."""
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(n):
            fn()
        best = min(best, time.perf_counter() - start)
    return best / n * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--evals", type=int, default=2000, help="evaluations per timing run")
    parser.add_argument("--repeats", type=int, default=7, help="timing runs; the best is reported")
    args = parser.parse_args()

    model = load_model("reach")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)

    def control_period() -> None:
        for _ in range(SUBSTEPS):
            mujoco.mj_step(model, data)

    physics_us = best_time_us(control_period, max(args.evals // 10, 50), args.repeats)

    rng = np.random.default_rng(0)
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    print(f"physics: {physics_us:.1f} us per control period ({SUBSTEPS} x mj_step, reach scene)")
    print(f"{'preset':<10}{'dim':>5}{'us/eval (y, J)':>17}{'ratio to physics':>19}")
    for name in OBS_PRESETS:
        stack = parse_observation(name, model)
        eval_us = best_time_us(lambda stack=stack: stack(model, data), args.evals, args.repeats)
        print(f"{name:<10}{stack.dim:>5}{eval_us:>17.1f}{eval_us / physics_us:>18.1%}")


if __name__ == "__main__":
    main()
