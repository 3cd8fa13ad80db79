"""Which orientation action can reach every goal of tsrl/UR5ePoseReach-v0? The paper's three scalar
products (x.x, y.y, z.z of world and TCP axes: the diagonal of R_wt) against the pose task's target z
and x axes of the TCP.

For each of N seeded goals, a local IK solve from home (DlsSolver, no restarts) to the goal's target
values of each action map; then the reached TCP pose is checked against the goal: position within
5 cm and orientation within 15 deg (the task's success), and the orientation error is reported.

    python benchmarks/pose_actions.py [--goals 200] [--env tsrl/UR5ePoseReach-v0] [--save [NAME]]

--save writes one row per goal and action (met, position error, orientation error) to
docs/results/benchmarks/NAME/ (default pose-actions) with meta.json (benchmarks/record.py); `table`
renders docs/tasks.md's table from them.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

ACTIONS = {
    "scalar products XX, YY, ZZ (the paper's)": "scalarProductXX(world, tcp), scalarProductYY(world, tcp), "
    "scalarProductZZ(world, tcp)",
    "vectorZ, vectorX (the pose task's)": "vectorZ(tcp), vectorX(tcp)",
}


def targets(name: str, goal: np.ndarray) -> np.ndarray:
    """The action map's target values that the goal pose (position, quaternion) asks for."""
    from tsrl.taskmaps.relabel import quaternion_to_rotation

    R = quaternion_to_rotation(goal[3:7])
    orientation = np.diag(R) if name.startswith("scalar") else np.concatenate([R[:, 2], R[:, 0]])
    return np.concatenate([goal[:3], orientation])


def measure(env_id: str, goals: int) -> list[dict[str, Any]]:
    """One row per action and seeded goal: env, action, goal (its seed), met (0/1: the task's success
    at the reached pose), position_error [m], orientation_error [deg]."""
    import gymnasium as gym
    import mujoco

    import tsrl  # noqa: F401  (registers the environments)
    from tsrl.ik import DlsSolver, IKOptions
    from tsrl.taskmaps import parse_spec

    env: Any = gym.make(env_id).unwrapped
    model, data, joints = env.model, mujoco.MjData(env.model), env.robot.joints
    pose = parse_spec(f"position({env.robot.tcp}), quaternion({env.robot.tcp})", model, joints)
    tol_pos, tol_deg = env.task.success.position, env.task.success.orientation
    rows = []
    for name, spec in ACTIONS.items():
        task_map = parse_spec(f"position({env.robot.tcp}), {spec}", model, joints)
        solver = DlsSolver(model, task_map, joints, IKOptions(restarts=0, max_iters=300))
        for seed in range(goals):
            goal = env.reset(seed=seed)[0]["desired_goal"]
            env.bound_robot.reset_to_home(env.model, data)
            result = solver.solve(data, targets(name, goal))
            data.qpos[env.bound_robot.qpos] = result.q
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            y = pose(model, data).y
            angle = float(np.degrees(2 * np.arccos(min(1.0, abs(y[3:7] @ goal[3:7])))))
            distance = float(np.linalg.norm(y[:3] - goal[:3]))
            met = int(distance < tol_pos and angle < tol_deg)
            rows.append(
                {
                    "env": env_id,
                    "action": name,
                    "goal": seed,
                    "met": met,
                    "position_error": distance,
                    "orientation_error": angle,
                }
            )
    return rows


def render(rows: list[dict[str, Any]]) -> list[str]:
    """docs/tasks.md's table (markdown lines) from `measure`'s rows (or their CSV strings)."""
    actions = list(dict.fromkeys(r["action"] for r in rows))
    n = len([r for r in rows if r["action"] == actions[0]])
    lines = [
        f"{rows[0]['env']}: {n} seeded goals, a local IK solve from home per goal.",
        "",
        "| orientation action | goals met | orientation error median [deg] | 90th percentile [deg] |",
        "| --- | ---: | ---: | ---: |",
    ]
    for name in actions:
        group = [r for r in rows if r["action"] == name]
        errors = [float(r["orientation_error"]) for r in group]
        met = sum(int(r["met"]) for r in group)
        lines.append(
            f"| {name} | {met}/{len(group)} | {np.median(errors):.1f} | {np.percentile(errors, 90):.1f} |"
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--goals", type=int, default=200)
    parser.add_argument("--env", default="tsrl/UR5ePoseReach-v0")
    add_save_argument(parser, "pose-actions")
    args = parser.parse_args()
    with Measurement(args.save, __file__, "table", "docs/tasks.md") as out:
        rows = measure(args.env, args.goals)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))


if __name__ == "__main__":
    main()
