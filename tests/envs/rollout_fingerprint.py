"""Seeded rollouts of the built-in environments: the fingerprint that refactors of the env step must keep.

`rollouts()` runs every case below (each action mode, observation presets and specs, both tasks, the
single IK step and the iterated one) and returns every observation, reward and info entry as arrays.
`python tests/envs/rollout_fingerprint.py --record` stores them in `data/rollouts.npz` and prints
their SHA-256; `python tests/envs/rollout_fingerprint.py` prints the SHA-256 of the current code's
rollouts and whether they are bit-identical to the stored ones.
"""

from __future__ import annotations

import argparse
import hashlib
from pathlib import Path

import gymnasium as gym
import numpy as np

import tsrl  # registers the environments

REFERENCE = Path(__file__).parent / "data" / "rollouts.npz"
EPISODES = 4  # of 50 steps each: 200 steps per case
#: Pick-and-place spec for the case that grasps: the policy below reads the box and the goal.
GRASP_SPEC = "position(tcp), position(box), position(target), velocity(position(box)), fs2"

#: (name, env id, make kwargs, policy): "random" samples seeded actions in [-1, 1]; "grasp" drives
#: the cup to the box with suction on, then towards the goal (contacts, adhesion, a moving box).
CASES: tuple[tuple[str, str, dict, str], ...] = (
    ("reach_fs2_taskspace", "tsrl/UR5eReach-v0", {"obs": "fs2", "action": "taskspace"}, "random"),
    ("reach_fs1_orient", "tsrl/UR5eReach-v0", {"obs": "fs1", "action": "taskspace_orient"}, "random"),
    ("reach_baseline_joint", "tsrl/UR5eReach-v0", {"obs": "baseline", "action": "joint"}, "random"),
    (
        "reach_simple_ik3",
        "tsrl/UR5eReach-v0",
        {"obs": "simple, jointState", "action": "taskspace", "ik_iterations": 3, "success_radius": 0.1},
        "random",
    ),
    ("pick_fs1_taskspace", "tsrl/UR5ePickPlace-v0", {"obs": "fs1", "action": "taskspace"}, "random"),
    ("pick_fs0_orient", "tsrl/UR5ePickPlace-v0", {"obs": "fs0", "action": "taskspace_orient"}, "random"),
    ("pick_simple_joint", "tsrl/UR5ePickPlace-v0", {"obs": "simple", "action": "joint"}, "random"),
    ("pick_grasp", "tsrl/UR5ePickPlace-v0", {"obs": GRASP_SPEC, "action": "taskspace"}, "grasp"),
    # Every registered task as its file defines it (observation, action, goal, penalties).
    *((f"task_{env_id.removeprefix('tsrl/')}", env_id, {}, "random") for env_id in tsrl.ENV_IDS),
)
#: Info entries recorded for every task; a task's other numeric entries (angle, penalty, ...) are
#: recorded too, by the names its reset info has.
INFO_KEYS = ("is_success", "distance", "ik_error")


def _grasp_action(obs: np.ndarray, carrying: bool) -> np.ndarray:
    tcp, box, goal = obs[0:3], obs[3:6], obs[6:9]
    target = goal + [0.0, 0.0, 0.02] if carrying else box + [0.0, 0.0, 0.015]
    return np.append(np.clip((target - tcp) / 0.05, -0.6, 0.6), 1.0)


def rollout(env_id: str, kwargs: dict, policy: str) -> dict[str, np.ndarray]:
    """EPISODES seeded episodes; returns arrays keyed by what they hold (one row per step or reset)."""
    env = gym.make(env_id, **kwargs)
    rng = np.random.default_rng(0)
    env.action_space.seed(0)
    rows: dict[str, list] = {k: [] for k in ("observation", "achieved_goal", "desired_goal", "reward", "end")}
    rows["unstable"] = []
    info_keys: tuple[str, ...] = ()
    for episode in range(EPISODES):
        obs, info = env.reset(seed=100 + episode)
        if not info_keys:
            info_keys = (*INFO_KEYS, *sorted(set(info) - set(INFO_KEYS) - {"physics_unstable"}))
            rows |= {k: [] for k in info_keys}
        carrying, done = False, False
        while True:
            for k in ("observation", "achieved_goal", "desired_goal"):
                rows[k].append(obs[k])
            for k in info_keys:
                rows[k].append(float(info[k]))
            rows["unstable"].append(bool(info.get("physics_unstable", False)))
            if done:
                break
            if policy == "random":
                action = rng.uniform(-1.0, 1.0, env.action_space.shape)
            else:
                y = obs["observation"]
                carrying = carrying or np.linalg.norm(y[0:3] - y[3:6] - [0, 0, 0.02]) < 0.01
                action = _grasp_action(y, carrying)
            obs, reward, terminated, truncated, info = env.step(action)
            rows["reward"].append(reward)
            rows["end"].append((terminated, truncated))
            done = terminated or truncated
    env.close()
    return {k: np.asarray(v, dtype=np.float64) for k, v in rows.items()}


def rollouts() -> dict[str, np.ndarray]:
    """Every case's arrays, keyed "case/array"."""
    out = {}
    for name, env_id, kwargs, policy in CASES:
        for key, value in rollout(env_id, kwargs, policy).items():
            out[f"{name}/{key}"] = value
    return out


def digest(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the keys and the exact bytes of every array."""
    h = hashlib.sha256()
    for key in sorted(arrays):
        h.update(key.encode())
        h.update(np.ascontiguousarray(arrays[key], dtype=np.float64).tobytes())
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", action="store_true", help="store the current rollouts as the reference")
    args = parser.parse_args()
    arrays = rollouts()
    print(f"current rollouts: {digest(arrays)}")
    if args.record:
        REFERENCE.parent.mkdir(exist_ok=True)
        np.savez_compressed(REFERENCE, **arrays)
        print(f"recorded {REFERENCE}")
        return
    with np.load(REFERENCE) as ref:
        reference = {k: ref[k] for k in ref.files}
    print(f"reference:        {digest(reference)}")
    if digest(reference) == digest(arrays):
        print("bit-identical")
        return
    for name, *_ in CASES:  # which cases changed, and which are new
        keys = sorted(k for k in arrays if k.startswith(f"{name}/"))
        if not any(k in reference for k in keys):
            print(f"  {name}: new (no reference yet)")
        elif digest({k: arrays[k] for k in keys}) != digest({k: reference.get(k, np.zeros(0)) for k in keys}):
            print(f"  {name}: DIFFERENT")
    print("DIFFERENT")


if __name__ == "__main__":
    main()
