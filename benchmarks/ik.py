"""IK benchmark: tsrl.ik.DlsSolver against mink 1.3 on the same targets of any robot, in one run.

    pip install -e ".[bench]"
    python benchmarks/ik.py                    # the UR5e: 200 global + 200 local targets, seed 0
    python benchmarks/ik.py --robot panda      # a built-in robot, or a robot's TOML file
    python benchmarks/ik.py --ablation         # what each ingredient of the solver adds (global targets)
    python benchmarks/ik.py ... --save [NAME]  # and write the per-target results (benchmarks/record.py)

Both solvers load OUR model of the robot (`tsrl.robots.load_robot(...).load_model()`) and reach for
the full pose of its TCP frame, moving the robot's joints. A solve succeeds when the position error is
<= 1e-4 m and the orientation error is <= 1e-4 rad, measured the same way for both (`pose_error`) on
the configuration each one returns.

- global: start at the robot's home; target = forward kinematics of a configuration drawn uniformly
  within the joint limits (any IK branch may be needed).
- local (RL-sized): start at home + U(-0.3, 0.3) rad per joint (clipped to the limits); target = the
  start pose moved by up to 5 cm (uniform in a ball) and turned by up to 5 degrees about a random axis.

Ours: `DlsSolver.solve` with its defaults and tol = 5e-5 on ||(dp, dquat)||; since ||dquat|| = 2 sin(angle/4)
~ angle / 2, that bound implies both tolerances above. mink (set up as its own examples do): one
FrameTask (position and orientation cost 1), ConfigurationLimit, a VelocityLimit that bounds each
joint's step to 0.2 rad per iteration, global damping 1e-3, the daqp solver that mink installs,
and a loop that integrates each step and stops as soon as `pose_error` meets the tolerances (at most
300 iterations). The step bound and lm_damping = 0 gave mink its best global success rate among
steps {none, 0.2, 0.5, 1.0} rad and lm_damping {0, 0.1, 1}. Ours and mink alternate target by
target, so machine load hits both alike. Times are wall-clock per full solve, start
configuration to answer.

--save writes one row per target and solver (success, iterations, seconds) and setup.json (robot,
versions, targets, seed) to docs/results/benchmarks/NAME/ (default ik-ablation, or ik-ROBOT, with
-posture under --posture); `table` and `ablation_table` render docs/ik.md's tables from them.
"""

from __future__ import annotations

import argparse
import gc
import json
import time
from collections.abc import Callable
from importlib.metadata import version
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

if TYPE_CHECKING:  # the measuring functions import these; the table renderers need none of them
    import mujoco

    from tsrl.robots import Robot
    from tsrl.taskmaps import TaskMap

POS_TOL = 1e-4  # m
ANG_TOL = 1e-4  # rad
OUR_TOL = 5e-5  # on ||(dp [m], dquat)||, implies POS_TOL and ANG_TOL
MINK_STEP = 0.2  # rad per joint per iteration
MINK_DAMPING = 1e-3
MINK_MAX_ITERS = 300
MINK_DT = 1.0  # s; only the step bound MINK_STEP / MINK_DT * MINK_DT depends on it
LOCAL_START_SPREAD = 0.3  # rad
LOCAL_MAX_MOVE = 0.05  # m
LOCAL_MAX_TURN = np.deg2rad(5.0)  # rad


class Case(NamedTuple):
    q_start: np.ndarray  # (n,) the robot's joints
    pos: np.ndarray  # (3,) target tcp position, world
    quat: np.ndarray  # (4,) target tcp orientation (w, x, y, z), world


class Outcome(NamedTuple):
    success: bool
    iterations: int
    seconds: float


class Bench(NamedTuple):
    """The robot under test: its model, description and the map of its TCP's pose."""

    model: mujoco.MjModel
    robot: Robot
    pose: TaskMap  # position(tcp), quaternion(tcp): (7,)
    home: np.ndarray  # (n,)


def make_bench(robot: str) -> Bench:
    from tsrl.robots import load_robot
    from tsrl.taskmaps import parse_spec

    described = load_robot(robot)
    model = described.load_model()
    pose = parse_spec(f"position({described.tcp}), quaternion({described.tcp})", model)
    return Bench(model, described, pose, described.home_q(model))


def tcp_pose(bench: Bench, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), quaternion (4,)) of the TCP frame at the kinematics held in data."""
    y = bench.pose(bench.model, data).y
    return y[:3], y[3:]


def pose_error(bench: Bench, data: mujoco.MjData, case: Case) -> tuple[float, float]:
    """(position error [m], rotation angle between reached and target orientation [rad])."""
    pos, quat = tcp_pose(bench, data)
    angle = 2.0 * np.arccos(min(1.0, abs(float(quat @ case.quat))))
    return float(np.linalg.norm(pos - case.pos)), float(angle)


def reached(bench: Bench, data: mujoco.MjData, case: Case) -> bool:
    dp, dangle = pose_error(bench, data, case)
    return dp <= POS_TOL and dangle <= ANG_TOL


def global_cases(bench: Bench, rng: np.random.Generator, n: int) -> list[Case]:
    import mujoco

    from tsrl.kinematics import forward_kinematics, random_configurations

    model, joints = bench.model, bench.robot.joints
    data = mujoco.MjData(model)
    cases = []
    for q in random_configurations(model, rng, n, joints):
        forward_kinematics(model, data, q, joints)
        cases.append(Case(bench.home.copy(), *tcp_pose(bench, data)))
    return cases


def local_cases(bench: Bench, rng: np.random.Generator, n: int) -> list[Case]:
    import mujoco

    from tsrl.kinematics import forward_kinematics, joint_limits

    model, joints = bench.model, bench.robot.joints
    data = mujoco.MjData(model)
    lo, hi = joint_limits(model, joints).T
    cases = []
    for _ in range(n):
        spread = rng.uniform(-LOCAL_START_SPREAD, LOCAL_START_SPREAD, len(joints))
        q_start = np.clip(bench.home + spread, lo, hi)
        forward_kinematics(model, data, q_start, joints)
        pos, quat = tcp_pose(bench, data)
        direction = rng.normal(size=3)
        move = direction / np.linalg.norm(direction) * LOCAL_MAX_MOVE * rng.uniform() ** (1 / 3)
        axis = rng.normal(size=3)
        turn = np.empty(4)
        mujoco.mju_axisAngle2Quat(turn, axis / np.linalg.norm(axis), LOCAL_MAX_TURN * rng.uniform())
        target_quat = np.empty(4)
        mujoco.mju_mulQuat(target_quat, quat, turn)
        cases.append(Case(q_start, pos + move, target_quat))
    return cases


class Ours:
    """DlsSolver.solve on position(tcp), quaternion(tcp); `with_value` passes the start value as the env does."""

    def __init__(self, bench: Bench, with_value: bool = False, **options: Any):
        import mujoco

        from tsrl.ik import DlsSolver, IKOptions
        from tsrl.kinematics import arm_qpos_indices, forward_kinematics

        self.forward_kinematics = forward_kinematics
        self.bench, self.data = bench, mujoco.MjData(bench.model)
        self.qadr = arm_qpos_indices(bench.model, bench.robot.joints)
        self.with_value = with_value
        options = {"tol": OUR_TOL, **options}
        self.solver = DlsSolver(bench.model, bench.pose, bench.robot.joints, IKOptions(**options))

    def __call__(self, case: Case) -> Outcome:
        model, data, joints = self.bench.model, self.data, self.bench.robot.joints
        target = np.concatenate([case.pos, case.quat])
        value = None
        if self.with_value:  # what the environment already holds at the start of a step
            self.forward_kinematics(model, data, case.q_start, joints)
            value = self.bench.pose(model, data)
        else:
            data.qpos[self.qadr] = case.q_start
        start = time.perf_counter()
        result = self.solver.solve(data, target, value)
        seconds = time.perf_counter() - start
        self.forward_kinematics(model, data, result.q, joints)
        return Outcome(reached(self.bench, data, case), result.iterations, seconds)


class Mink:
    """mink 1.3: FrameTask + ConfigurationLimit + VelocityLimit, daqp, integrate until reached."""

    def __init__(self, bench: Bench):
        import mujoco

        from tsrl.kinematics import arm_qpos_indices

        try:
            import mink
        except ImportError as err:  # a benchmark-only dependency
            raise SystemExit('mink is missing: pip install -e ".[bench]"') from err

        model, robot = bench.model, bench.robot
        self.mink, self.bench = mink, bench
        self.configuration = mink.Configuration(model)
        kind = "site" if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, robot.tcp) >= 0 else "body"
        self.task = mink.FrameTask(robot.tcp, kind, position_cost=1.0, orientation_cost=1.0)
        self.limits = [
            mink.ConfigurationLimit(model),
            mink.VelocityLimit(model, {name: MINK_STEP / MINK_DT for name in robot.joints}),
        ]
        self.qadr = arm_qpos_indices(model, robot.joints)
        self.qpos = model.qpos0.copy()  # the other coordinates stay at qpos0

    def __call__(self, case: Case) -> Outcome:
        mink, configuration = self.mink, self.configuration
        data = configuration.data
        self.task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(wxyz=case.quat), case.pos))
        self.qpos[self.qadr] = case.q_start
        start = time.perf_counter()
        configuration.update(self.qpos)
        success, iterations = False, 0
        while iterations < MINK_MAX_ITERS and not success:
            v = mink.solve_ik(
                configuration, [self.task], MINK_DT, "daqp", damping=MINK_DAMPING, limits=self.limits
            )
            configuration.integrate_inplace(v, MINK_DT)
            iterations += 1
            success = reached(self.bench, data, case)
        seconds = time.perf_counter() - start
        return Outcome(reached(self.bench, data, case), iterations, seconds)


def run(solvers: dict[str, Callable[[Case], Outcome]], cases: list[Case]) -> dict[str, list[Outcome]]:
    """Every solver on every case, the solvers' order rotating from case to case."""
    out: dict[str, list[Outcome]] = {name: [] for name in solvers}
    names = list(solvers)
    gc.disable()
    try:
        for i, case in enumerate(cases):
            for name in names[i % len(names) :] + names[: i % len(names)]:
                out[name].append(solvers[name](case))
    finally:
        gc.enable()
    return out


def outcome_rows(key: dict[str, str], outcomes: list[Outcome]) -> list[dict[str, Any]]:
    """One row per target: `key`'s columns, then target (index), success (0/1), iterations, seconds."""
    return [
        key | {"target": i, "success": int(o.success), "iterations": o.iterations, "seconds": o.seconds}
        for i, o in enumerate(outcomes)
    ]


def summary(rows: list[dict[str, Any]]) -> tuple[float, float, float, float]:
    """(success rate, median iterations, median time [us], 90th-percentile time [us]) of per-target
    rows (`outcome_rows`, or their CSV strings)."""
    t = np.array([float(r["seconds"]) for r in rows]) * 1e6
    return (
        float(np.mean([int(r["success"]) for r in rows])),
        float(np.median([int(r["iterations"]) for r in rows])),
        float(np.median(t)),
        float(np.percentile(t, 90)),
    )


#: What each ingredient of the solver adds (--ablation), and the full method without adaptive damping.
ABLATION: dict[str, dict[str, Any]] = {
    "plain DLS (damping 1e-4, no step bound, one start)": {
        "restarts": 0,
        "adaptive_damping": 0.0,
        "damping": 1e-4,
        "max_step": 1e9,
        "max_iters": 300,
    },
    "+ step bound 1 rad": {"restarts": 0, "adaptive_damping": 0.0, "damping": 1e-4, "max_iters": 300},
    "+ adaptive damping 1e-6 + 1e-3 err^2": {"restarts": 0, "max_iters": 300},
    "+ restarts after a stall (the defaults)": {},
    "the defaults with fixed damping 1e-3": {"adaptive_damping": 0.0, "damping": 1e-3},
}


def measure_ablation(bench: Bench, cases: list[Case], **extra: Any) -> list[dict[str, Any]]:
    """Per-target rows (variant, target, success, iterations, seconds) of each ABLATION variant."""
    rows = []
    for name, options in ABLATION.items():
        outcomes = run({name: Ours(bench, **extra, **options)}, cases)[name]
        rows += outcome_rows({"variant": name}, outcomes)
    return rows


def measure(bench: Bench, sets: dict[str, list[Case]], **extra: Any) -> list[dict[str, Any]]:
    """Per-target rows (set, solver, target, success, iterations, seconds): tsrl and mink on every
    set, and on the local set also tsrl given the start's map value."""
    ours, ours_value, baseline = Ours(bench, **extra), Ours(bench, with_value=True, **extra), Mink(bench)
    rows = []
    for set_name, cases in sets.items():
        solvers: dict[str, Callable[[Case], Outcome]] = {"tsrl": ours, "mink": baseline}
        if set_name == "local":
            solvers["tsrl, initial_value"] = ours_value
        for name, outcomes in run(solvers, cases).items():
            rows += outcome_rows({"set": set_name, "solver": name}, outcomes)
    return rows


def setup(bench: Bench, args: argparse.Namespace) -> dict[str, Any]:
    """What the rows were measured on: robot, joints, TCP, targets per set, seed, posture, versions."""
    import mujoco

    versions = {"mujoco": mujoco.__version__}
    if not args.ablation:
        versions |= {"mink": version("mink"), "daqp": version("daqp")}
    return {
        "robot": bench.robot.name,
        "joints": list(bench.robot.joints),
        "tcp": bench.robot.tcp,
        "targets_per_set": args.n,
        "seed": args.seed,
        "posture": args.posture,
        "versions": versions,
    }


def render_ablation(rows: list[dict[str, Any]]) -> list[str]:
    """docs/ik.md's ablation table (markdown lines) from `measure_ablation`'s rows (or their CSV strings)."""
    lines = [
        "| global targets, tsrl | success | median iters | median time [us] | p90 time [us] |",
        "| --- | --- | --- | --- | --- |",
    ]
    for name in dict.fromkeys(r["variant"] for r in rows):
        group = [r for r in rows if r["variant"] == name]
        rate, iters, median, p90 = summary(group)
        solved = sum(int(r["success"]) for r in group)
        lines.append(
            f"| {name} | {rate:.1%} ({solved}/{len(group)}) | {iters:.0f} | {median:.0f} | {p90:.0f} |"
        )
    return lines


def render(rows: list[dict[str, Any]], info: dict[str, Any]) -> list[str]:
    """docs/ik.md's table against mink (markdown lines) from `measure`'s rows (or their CSV strings)
    and `setup`'s description."""
    v = info["versions"]
    posture = ", tsrl with the posture term toward home" if info["posture"] else ""
    described = (
        f"Robot {info['robot']} (TCP `{info['tcp']}`), {info['targets_per_set']} targets per set, "
        f"seed {info['seed']}{posture}; mujoco {v['mujoco']}, mink {v['mink']}, daqp {v['daqp']}."
    )
    lines = [
        described,
        "",
        "| set | solver | success | median iters | median time [us] | p90 time [us] |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    medians: dict[tuple[str, str], float] = {}
    for set_name, solver in dict.fromkeys((r["set"], r["solver"]) for r in rows):
        group = [r for r in rows if (r["set"], r["solver"]) == (set_name, solver)]
        rate, iters, median, p90 = summary(group)
        medians[set_name, solver] = median
        solved = f"{rate:.1%} ({sum(int(r['success']) for r in group)}/{len(group)})"
        lines.append(f"| {set_name} | {solver} | {solved} | {iters:.0f} | {median:.0f} | {p90:.0f} |")
    ratios = [
        f"{s} {medians[s, 'tsrl'] / medians[s, 'mink']:.2f}" for s in dict.fromkeys(s for s, _ in medians)
    ]
    return lines + ["", f"Median time tsrl / mink: {', '.join(ratios)}."]


SETUP_JSON = "setup.json"


def ablation_table(data_dir: Path) -> list[str]:
    """The ablation table from the data `--ablation --save` wrote to `data_dir`."""
    return render_ablation(read_rows(data_dir / DATA_CSV))


def table(data_dir: Path) -> list[str]:
    """The table against mink from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV), json.loads((data_dir / SETUP_JSON).read_text()))


#: --save's default NAME, replaced by ik-ablation or ik-ROBOT[-posture].
DEFAULT_NAME = "ik-ROBOT"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=200, help="targets per set")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ablation", action="store_true", help="only ours, ingredient by ingredient")
    parser.add_argument(
        "--robot", default="ur5e", help="a built-in robot (tsrl.robots.ROBOTS) or a TOML file"
    )
    parser.add_argument(
        "--posture", action="store_true", help="ours with the null-space posture term toward home"
    )
    add_save_argument(parser, DEFAULT_NAME)
    args = parser.parse_args()
    if args.save == DEFAULT_NAME:
        robot = Path(args.robot).stem
        args.save = "ik-ablation" if args.ablation else f"ik-{robot}" + ("-posture" if args.posture else "")

    bench = make_bench(args.robot)
    rng = np.random.default_rng(args.seed)
    sets = {"global": global_cases(bench, rng, args.n), "local": local_cases(bench, rng, args.n)}
    extra: dict[str, Any] = {"posture": tuple(bench.home)} if args.posture else {}
    info = setup(bench, args)
    renderer = "ablation_table" if args.ablation else "table"
    with Measurement(args.save, __file__, renderer, "docs/ik.md") as out:
        if args.ablation:
            rows = measure_ablation(bench, sets["global"], **extra)
        else:
            rows = measure(bench, sets, **extra)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
            (out / SETUP_JSON).write_text(json.dumps(info, indent=2) + "\n")
    print(f"robot {bench.robot.name}: joints {', '.join(bench.robot.joints)}; TCP {bench.robot.tcp}")
    print(f"success: |dp| <= {POS_TOL} m and angle <= {ANG_TOL} rad\n")
    print("\n".join(render_ablation(rows) if args.ablation else render(rows, info)))


if __name__ == "__main__":
    main()
