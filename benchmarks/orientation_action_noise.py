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

    python benchmarks/orientation_action_noise.py [--episodes 20] [--sigmas 0 0.05 0.1 0.2]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import mujoco
import numpy as np

import tsrl  # noqa: F401  (registers the environments)
from tsrl.envs.actions import ACTION_PRESETS
from tsrl.envs.solvers import PickPlaceSolver
from tsrl.taskmaps import parse_spec

ENV_ID = "tsrl/UR5ePickPlace-v0"
#: The paper's orientation action: the parts of `taskspace_orient` after the TCP position.
SCALAR_PRODUCTS = ", ".join(part.map for part in ACTION_PRESETS["taskspace_orient"].parts[1:])


def run(action: str, sigma: float, episodes: int, noisy_orientation: bool = True) -> tuple[float, np.ndarray]:
    """Success rate and each episode's largest cup tilt [deg] of the noisy scripted controller."""
    env = gym.make(ENV_ID, action=action)
    controller = PickPlaceSolver(env.unwrapped)  # reads the positions it needs from the env's state
    tcp = env.unwrapped.model.site(env.unwrapped.robot.tcp).id
    data = env.unwrapped.data
    rng = np.random.default_rng(0)
    successes, tilts = 0, np.zeros(episodes)
    for episode in range(episodes):
        obs, _ = env.reset(seed=episode)
        controller.reset(obs)
        info: dict = {}
        for _ in range(env.spec.max_episode_steps):
            # The solver's action before its float32 cast (act() casts): position, held values, suction.
            y = controller.positions(env.unwrapped.model, data).y
            scripted = controller.control({name: y[s] for name, s in controller.positions.slices.items()})
            action_vector = np.concatenate([scripted[:3], controller.hold, scripted[3:]])
            noise = sigma * rng.standard_normal(action_vector.shape)
            if not noisy_orientation:
                noise[3 : 3 + controller.hold.size] = 0.0
            obs, _, terminated, truncated, info = env.step((action_vector + noise).astype(np.float32))
            cup_down = -data.site_xmat[tcp].reshape(3, 3)[2, 2]  # -(world z . TCP z)
            tilts[episode] = max(tilts[episode], np.degrees(np.arccos(np.clip(cup_down, -1.0, 1.0))))
            if terminated or truncated:
                break
        successes += bool(info["is_success"])
    env.close()
    return successes / episodes, tilts


def jacobian_singular_values() -> np.ndarray:
    """Singular values of d(x.x, y.y, z.z)/dq at the UR5e's home (cup down)."""
    env = gym.make(ENV_ID).unwrapped
    data = mujoco.MjData(env.model)
    env.bound_robot.reset_to_home(env.model, data)
    mujoco.mj_fwdPosition(env.model, data)  # frames and the joint axes' motion (cdof) for Jacobians
    value = parse_spec(SCALAR_PRODUCTS, env.model, env.robot.joints)(env.model, data)
    env.close()
    print(f"(x.x, y.y, z.z) at home: {np.round(value.y, 6)}")
    return np.linalg.svd(value.J, compute_uv=False)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 0.05, 0.1, 0.2])
    args = parser.parse_args()
    print(
        f"{ENV_ID}: scripted pick-and-place with Gaussian action noise, {args.episodes} seeded episodes each\n"
    )
    print("| action | noise on | sigma | success | largest tilt, median [deg] | largest tilt, max [deg] |")
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    rows = [("taskspace", True), ("taskspace_orient", True), ("taskspace_orient", False)]
    for action, noisy_orientation in rows:
        where = "every dimension" if noisy_orientation else "all but the scalar products"
        for sigma in args.sigmas:
            success, tilts = run(action, sigma, args.episodes, noisy_orientation)
            print(
                f"| {action} | {where} | {sigma:g} | {success:.2f} | {np.median(tilts):.1f} | {tilts.max():.1f} |",
                flush=True,
            )
    print()
    print(
        f"singular values of d(x.x, y.y, z.z)/dq at home: {np.array2string(jacobian_singular_values(), precision=4)}"
    )


if __name__ == "__main__":
    main()
