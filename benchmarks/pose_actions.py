"""Which orientation action can reach every goal of tsrl/UR5ePoseReach-v0? The paper's three scalar
products (x.x, y.y, z.z of world and TCP axes: the diagonal of R_wt) against the pose task's target z
and x axes of the TCP.

For each of N seeded goals, a local IK solve from home (DlsSolver, no restarts) to the goal's target
values of each action map; then the reached TCP pose is checked against the goal: position within
5 cm and orientation within 15 deg (the task's success), and the orientation error is reported.

    python benchmarks/pose_actions.py [--goals 200] [--env tsrl/UR5ePoseReach-v0]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import mujoco
import numpy as np

import tsrl  # noqa: F401  (registers the environments)
from tsrl.ik import DlsSolver, IKOptions
from tsrl.taskmaps import parse_spec
from tsrl.taskmaps.relabel import quaternion_to_rotation

ACTIONS = {
    "scalar products XX, YY, ZZ (the paper's)": "scalarProductXX(world, tcp), scalarProductYY(world, tcp), "
    "scalarProductZZ(world, tcp)",
    "vectorZ, vectorX (the pose task's)": "vectorZ(tcp), vectorX(tcp)",
}


def targets(name: str, goal: np.ndarray) -> np.ndarray:
    """The action map's target values that the goal pose (position, quaternion) asks for."""
    R = quaternion_to_rotation(goal[3:7])
    orientation = np.diag(R) if name.startswith("scalar") else np.concatenate([R[:, 2], R[:, 0]])
    return np.concatenate([goal[:3], orientation])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goals", type=int, default=200)
    parser.add_argument("--env", default="tsrl/UR5ePoseReach-v0")
    args = parser.parse_args()
    env = gym.make(args.env).unwrapped
    model, data, joints = env.model, mujoco.MjData(env.model), env.robot.joints
    pose = parse_spec(f"position({env.robot.tcp}), quaternion({env.robot.tcp})", model, joints)
    tol_pos, tol_deg = env.task.success.position, env.task.success.orientation
    print(f"{args.env}: {args.goals} seeded goals, a local IK solve from home per goal\n")
    print("| orientation action | goals met | orientation error median [deg] | 90th percentile [deg] |")
    print("| --- | ---: | ---: | ---: |")
    for name, spec in ACTIONS.items():
        task_map = parse_spec(f"position({env.robot.tcp}), {spec}", model, joints)
        solver = DlsSolver(model, task_map, joints, IKOptions(restarts=0, max_iters=300))
        met, errors = 0, []
        for seed in range(args.goals):
            goal = env.reset(seed=seed)[0]["desired_goal"]
            env.bound_robot.reset_to_home(env.model, data)
            result = solver.solve(data, targets(name, goal))
            data.qpos[env.bound_robot.qpos] = result.q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            y = pose(model, data).y
            angle = np.degrees(2 * np.arccos(min(1.0, abs(y[3:7] @ goal[3:7]))))
            errors.append(angle)
            met += bool(np.linalg.norm(y[:3] - goal[:3]) < tol_pos and angle < tol_deg)
        print(f"| {name} | {met}/{args.goals} | {np.median(errors):.1f} | {np.percentile(errors, 90):.1f} |")


if __name__ == "__main__":
    main()
