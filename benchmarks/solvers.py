"""How many sampled goals do the scripted solvers of the built-in tasks reach? A table of success rates
over N seeded episodes per task (seeds 0..N-1) for every task of the solver registry
(`tsrl.envs.solvers.SOLVERS`, both robots), in the task's own action, and for the obstacle tasks the
episodes in which the obstacle is in contact at reset (before any action), and those in which the robot
touched it (a penalised step): at all, already on the first step, and still on the last (resting at the
goal).

The tests (`tests/envs/test_tasks.py`, `tests/envs/test_pick_place_scripted.py`) assert at least 99 (95
for pick-and-place) of 100; this prints the rate on more goals.

    python benchmarks/solvers.py [--episodes 1000] [--tasks UR5ePoseReach-v0 ...]
"""

from __future__ import annotations

import argparse
import warnings

import gymnasium as gym
import mujoco
import numpy as np

import tsrl  # noqa: F401  (registers the environments)
from tsrl.envs.solvers import SOLVERS


def run(env_id: str, episodes: int) -> tuple[int, np.ndarray, list[int]]:
    """Successes; episodes with the obstacle in a contact at reset, and with a penalised step
    (`info["penalty"]` not 0) at all, on the first step and on the last step (4,); the seeds that
    failed."""
    with warnings.catch_warnings():  # v0 is measured on purpose: no out-of-date warning
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id)
    base = env.unwrapped
    obstacle = base.model.geom(base.task.obstacle.geom).id if base.task.obstacle else None
    solver = SOLVERS[env_id.removeprefix("tsrl/")](base)
    successes, touched, failed = 0, np.zeros(4, dtype=int), []
    for seed in range(episodes):
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
        successes += int(info["is_success"])
        touched += [at_reset, any(penalised), penalised[0], penalised[-1]]
        if not info["is_success"]:
            failed.append(seed)
    env.close()
    return successes, touched, failed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=1000, help="seeded episodes per task (seeds 0..N-1)")
    parser.add_argument(
        "--tasks", nargs="+", choices=list(SOLVERS), default=list(SOLVERS), help="built-in tasks"
    )
    args = parser.parse_args()
    print(
        "| task | solver | success | episodes: obstacle in contact at reset; touched at all / on step 1 / on the last "
        "| failed seeds |"
    )
    print("| --- | --- | ---: | ---: | --- |")
    for name in args.tasks:
        env_id, solver = f"tsrl/{name}", SOLVERS[name]
        successes, touched, failed = run(env_id, args.episodes)
        rate = f"{successes}/{args.episodes} ({100 * successes / args.episodes:.1f}%)"
        touching = f"{touched[0]}; " + " / ".join(map(str, touched[1:])) if "Obstacle" in env_id else "–"
        shown = ", ".join(map(str, failed[:8])) + (" ..." if len(failed) > 8 else "") or "none"
        print(f"| {env_id} | {solver.__name__} | {rate} | {touching} | {shown} |", flush=True)
    print(f"\n(numpy {np.__version__})")


if __name__ == "__main__":
    main()
