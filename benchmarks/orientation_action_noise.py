"""Why the paper's orientation action does not learn pick-and-place here: exploration noise on its three
scalar products tips the cup over, while the same noise on a cup-down action does not.

The scripted pick-and-place controller (`tsrl.envs.solvers.PickPlaceSolver`) runs closed loop on
tsrl/UR5ePickPlace-v0 in two action modes; Gaussian noise of standard deviation sigma, as DDPG's
exploration adds it (`TrainConfig.action_noise`, 0.2 by default), is added to its action before the env
clips it to [-1, 1]:

- `taskspace`: TCP position step + suction; the IK holds the cup pointing down.
- `taskspace_orient`: the paper's action: TCP position step + target values of the scalar products x.x,
  y.y, z.z of world and TCP axes + suction. The controller holds the scalar products' start values,
  (0, 0, -1) at home.

Noise goes on every dimension, or (last rows) on all but the scalar products. The table gives the success
rate over the seeded episodes and the largest tilt of the cup from pointing down (deg) per episode.

The last line gives why: the singular values of the Jacobian of (x.x, y.y, z.z) with respect to the
joints at home. With the cup down, z.z = -1 is the minimum of z.z, and x.x and y.y change to first order
only with the yaw about the cup's axis: the Jacobian has rank 1. The two tilts are invisible to the
linearised IK map, so nothing pulls the cup back to pointing down, and noisy targets tip it.

    python benchmarks/orientation_action_noise.py [--episodes 100] [--sigmas 0 0.05 0.1 0.2] [--save [NAME]]

--save writes one row per episode (action, noise on, sigma, seed, success, largest tilt) to
docs/results/benchmarks/orientation-action-noise/data.csv and the singular values to jacobian.csv
(benchmarks/record.py); `table` renders docs/tasks.md's table from them.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

ENV_ID = "tsrl/UR5ePickPlace-v0"
JACOBIAN_CSV = "jacobian.csv"
#: The table's rows: (action, noise on the scalar products too).
CASES = (("taskspace", True), ("taskspace_orient", True), ("taskspace_orient", False))


def noise_on(noisy_orientation: bool) -> str:
    """The table's "noise on" cell."""
    return "every dimension" if noisy_orientation else "all but the scalar products"


def scalar_products() -> str:
    """The paper's orientation action: the parts of `taskspace_orient` after the TCP position."""
    from tsrl.envs.actions import ACTION_PRESETS

    return ", ".join(part.map for part in ACTION_PRESETS["taskspace_orient"].parts[1:])


def run(action: str, sigma: float, episodes: int, noisy_orientation: bool = True) -> list[dict[str, Any]]:
    """One row per seeded episode (seeds 0..episodes-1) of the noisy scripted controller: success (0/1)
    and the episode's largest cup tilt from pointing down [deg]."""
    import gymnasium as gym

    import tsrl  # noqa: F401  (registers the environments)
    from tsrl.envs.solvers import PickPlaceSolver

    env = gym.make(ENV_ID, action=action)
    base: Any = env.unwrapped  # a tsrl TaskEnv
    controller = PickPlaceSolver(base)  # reads the positions it needs from the env's state
    tcp = base.model.site(base.robot.tcp).id
    data = base.data
    rng = np.random.default_rng(0)
    rows = []
    assert env.spec is not None and env.spec.max_episode_steps is not None
    for episode in range(episodes):
        obs, _ = env.reset(seed=episode)
        controller.reset(obs)
        info: dict = {}
        tilt = 0.0
        for _ in range(env.spec.max_episode_steps):
            # The solver's action before its float32 cast (act() casts): position, held values, suction.
            y = controller.positions(base.model, data).y
            scripted = controller.control({name: y[s] for name, s in controller.positions.slices.items()})
            action_vector = np.concatenate([scripted[:3], controller.hold, scripted[3:]])
            noise = sigma * rng.standard_normal(action_vector.shape)
            if not noisy_orientation:
                noise[3 : 3 + controller.hold.size] = 0.0
            obs, _, terminated, truncated, info = env.step((action_vector + noise).astype(np.float32))
            cup_down = -data.site_xmat[tcp].reshape(3, 3)[2, 2]  # -(world z . TCP z)
            tilt = max(tilt, float(np.degrees(np.arccos(np.clip(cup_down, -1.0, 1.0)))))
            if terminated or truncated:
                break
        rows.append(
            {
                "action": action,
                "noise_on": noise_on(noisy_orientation),
                "sigma": sigma,
                "seed": episode,
                "success": int(bool(info["is_success"])),
                "largest_tilt_deg": tilt,
            }
        )
    env.close()
    return rows


def jacobian_singular_values() -> tuple[np.ndarray, np.ndarray]:
    """(x.x, y.y, z.z) at the UR5e's home (cup down) and the singular values of its Jacobian d/dq."""
    import gymnasium as gym
    import mujoco

    import tsrl  # noqa: F401  (registers the environments)
    from tsrl.taskmaps import parse_spec

    env: Any = gym.make(ENV_ID).unwrapped
    data = mujoco.MjData(env.model)
    env.bound_robot.reset_to_home(env.model, data)
    mujoco.mj_fwdPosition(env.model, data)  # frames and the joint axes' motion (cdof) for Jacobians
    value = parse_spec(scalar_products(), env.model, env.robot.joints)(env.model, data)
    env.close()
    return value.y, np.linalg.svd(value.J, compute_uv=False)


def render(rows: list[dict[str, Any]], jacobian: list[dict[str, Any]]) -> list[str]:
    """The table (markdown lines) from `run`'s rows and the Jacobian's rows (index, value at home,
    singular value), or their CSV strings: one line per (action, noise on, sigma) in the rows' order."""
    lines = [
        "| action | noise on | sigma | episodes | success | largest tilt, median [deg] | largest tilt, max [deg] |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for action, where, sigma in dict.fromkeys((r["action"], r["noise_on"], r["sigma"]) for r in rows):
        mine = [r for r in rows if (r["action"], r["noise_on"], r["sigma"]) == (action, where, sigma)]
        wins = np.mean([int(r["success"]) for r in mine])
        tilts = np.array([float(r["largest_tilt_deg"]) for r in mine])
        lines.append(
            f"| `{action}` | {where} | {float(sigma):g} | {len(mine)} | {wins:.2f} | "
            f"{np.median(tilts):.1f} | {tilts.max():.1f} |"
        )
    at_home = ", ".join(f"{round(float(r['value_at_home']), 6) + 0.0:g}" for r in jacobian)
    singular = ", ".join(f"{float(r['singular_value']):.4f}" for r in jacobian)
    lines += [
        "",
        f"(x.x, y.y, z.z) at home: ({at_home}); singular values of its Jacobian d/dq there: {singular}.",
    ]
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV), read_rows(data_dir / JACOBIAN_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100, help="seeded episodes per row (seeds 0..N-1)")
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 0.05, 0.1, 0.2])
    add_save_argument(parser, "orientation-action-noise")
    args = parser.parse_args()
    print(
        f"{ENV_ID}: scripted pick-and-place with Gaussian action noise, {args.episodes} seeded episodes each\n"
    )
    with Measurement(args.save, __file__, "table", "docs/tasks.md") as out:
        rows: list[dict[str, Any]] = []
        for action, noisy_orientation in CASES:
            for sigma in args.sigmas:
                rows += run(action, sigma, args.episodes, noisy_orientation)
                print(render(rows, [])[-3], flush=True)
        value, singular = jacobian_singular_values()
        jacobian = [
            {"index": i, "value_at_home": float(v), "singular_value": float(s)}
            for i, (v, s) in enumerate(zip(value, singular, strict=True))
        ]
        if out is not None:
            write_rows(out / DATA_CSV, rows)
            write_rows(out / JACOBIAN_CSV, jacobian)
    print("\n".join(render(rows, jacobian)))


if __name__ == "__main__":
    main()
