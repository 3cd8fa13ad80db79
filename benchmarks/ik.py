"""IK benchmark: tsrl.ik.solve_ik against mink 1.3 on the same UR5e targets, in one run.

    pip install -e ".[bench]"
    python benchmarks/ik.py              # 200 global + 200 local targets, seed 0
    python benchmarks/ik.py --ablation   # what each ingredient of solve_ik adds (global targets)

Both solvers load OUR model (tsrl.assets.load_model("reach")) and reach for the full pose of the
`tcp` site. A solve succeeds when the position error is <= 1e-4 m and the orientation error is
<= 1e-4 rad, measured the same way for both (`pose_error`) on the configuration each one returns.

- global: start at HOME_Q; target = forward kinematics of a configuration drawn uniformly within
  the joint limits (any of the UR5e's IK branches may be needed).
- local (RL-sized): start at HOME_Q + U(-0.3, 0.3) rad per joint; target = the start pose moved by
  up to 5 cm (uniform in a ball) and turned by up to 5 degrees about a random axis.

Ours: `solve_ik` with its defaults and tol = 5e-5 on ||(dp, dquat)||; since ||dquat|| = 2 sin(angle/4)
~ angle / 2, that bound implies both tolerances above. mink (set up as its own examples do): one
FrameTask (position and orientation cost 1), ConfigurationLimit, a VelocityLimit that bounds each
joint's step to 0.2 rad per iteration, global damping 1e-3, the daqp solver that mink installs,
and a loop that integrates each step and stops as soon as `pose_error` meets the tolerances (at most
300 iterations). The step bound and lm_damping = 0 gave mink its best global success rate among
steps {none, 0.2, 0.5, 1.0} rad and lm_damping {0, 0.1, 1}. Ours and mink alternate target by
target, so machine load hits both alike. Times are wall-clock per full solve, start
configuration to answer.
"""

from __future__ import annotations

import argparse
import gc
import time
from collections.abc import Callable
from importlib.metadata import version
from typing import Any, NamedTuple

import mujoco
import numpy as np

try:
    import mink
except ImportError as err:  # a benchmark-only dependency
    raise SystemExit('mink is missing: pip install -e ".[bench]"') from err

from tsrl.assets import load_model
from tsrl.assets.ur5e import HOME_Q, JOINT_NAMES, TCP_SITE
from tsrl.ik import solve_ik
from tsrl.kinematics import arm_qpos_indices, forward_kinematics, random_configurations
from tsrl.taskmaps import TaskMap, parse_spec

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
    q_start: np.ndarray  # (6,)
    pos: np.ndarray  # (3,) target tcp position, world
    quat: np.ndarray  # (4,) target tcp orientation (w, x, y, z), world


class Outcome(NamedTuple):
    success: bool
    iterations: int
    seconds: float


def tcp_pose(model: mujoco.MjModel, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,), quaternion (4,)) of the tcp site at the kinematics held in data."""
    sid = model.site(TCP_SITE).id
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, data.site_xmat[sid])
    return data.site_xpos[sid].copy(), quat


def pose_error(model: mujoco.MjModel, data: mujoco.MjData, case: Case) -> tuple[float, float]:
    """(position error [m], rotation angle between reached and target orientation [rad])."""
    pos, quat = tcp_pose(model, data)
    angle = 2.0 * np.arccos(min(1.0, abs(float(quat @ case.quat))))
    return float(np.linalg.norm(pos - case.pos)), float(angle)


def reached(model: mujoco.MjModel, data: mujoco.MjData, case: Case) -> bool:
    dp, dangle = pose_error(model, data, case)
    return dp <= POS_TOL and dangle <= ANG_TOL


def global_cases(model: mujoco.MjModel, rng: np.random.Generator, n: int) -> list[Case]:
    data = mujoco.MjData(model)
    cases = []
    for q in random_configurations(model, rng, n):
        forward_kinematics(model, data, q)
        cases.append(Case(HOME_Q.copy(), *tcp_pose(model, data)))
    return cases


def local_cases(model: mujoco.MjModel, rng: np.random.Generator, n: int) -> list[Case]:
    data = mujoco.MjData(model)
    cases = []
    for _ in range(n):
        q_start = HOME_Q + rng.uniform(-LOCAL_START_SPREAD, LOCAL_START_SPREAD, 6)
        forward_kinematics(model, data, q_start)
        pos, quat = tcp_pose(model, data)
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
    """solve_ik on position(tcp), quaternion(tcp); `with_value` passes the start value as the env does."""

    def __init__(self, model: mujoco.MjModel, with_value: bool = False, **options: Any):
        self.model, self.data = model, mujoco.MjData(model)
        self.task_map: TaskMap = parse_spec(f"position({TCP_SITE}), quaternion({TCP_SITE})", model)
        self.qadr = arm_qpos_indices(model)
        self.with_value = with_value
        self.options = {"tol": OUR_TOL, **options}

    def __call__(self, case: Case) -> Outcome:
        model, data = self.model, self.data
        target = np.concatenate([case.pos, case.quat])
        value = None
        if self.with_value:  # what the environment already holds at the start of a step
            forward_kinematics(model, data, case.q_start)
            value = self.task_map(model, data)
        else:
            data.qpos[self.qadr] = case.q_start
        start = time.perf_counter()
        result = solve_ik(model, data, self.task_map, target, initial_value=value, **self.options)
        seconds = time.perf_counter() - start
        forward_kinematics(model, data, result.q)
        return Outcome(reached(model, data, case), result.iterations, seconds)


class Mink:
    """mink 1.3: FrameTask + ConfigurationLimit + VelocityLimit, daqp, integrate until reached."""

    def __init__(self, model: mujoco.MjModel):
        self.model = model
        self.configuration = mink.Configuration(model)
        self.task = mink.FrameTask(TCP_SITE, "site", position_cost=1.0, orientation_cost=1.0)
        self.limits = [
            mink.ConfigurationLimit(model),
            mink.VelocityLimit(model, {name: MINK_STEP / MINK_DT for name in JOINT_NAMES}),
        ]

    def __call__(self, case: Case) -> Outcome:
        configuration, model = self.configuration, self.model
        data = configuration.data
        self.task.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(wxyz=case.quat), case.pos))
        start = time.perf_counter()
        configuration.update(case.q_start)
        success, iterations = False, 0
        while iterations < MINK_MAX_ITERS and not success:
            v = mink.solve_ik(
                configuration, [self.task], MINK_DT, "daqp", damping=MINK_DAMPING, limits=self.limits
            )
            configuration.integrate_inplace(v, MINK_DT)
            iterations += 1
            success = reached(model, data, case)
        seconds = time.perf_counter() - start
        return Outcome(reached(model, data, case), iterations, seconds)


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


def summary(outcomes: list[Outcome]) -> tuple[float, float, float, float]:
    """(success rate, median iterations, median time [us], 90th-percentile time [us])."""
    t = np.array([o.seconds for o in outcomes]) * 1e6
    return (
        float(np.mean([o.success for o in outcomes])),
        float(np.median([o.iterations for o in outcomes])),
        float(np.median(t)),
        float(np.percentile(t, 90)),
    )


#: What each ingredient of solve_ik adds (--ablation), and the full method without adaptive damping.
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


def ablation(model: mujoco.MjModel, cases: list[Case]) -> None:
    print("| global targets, tsrl | success | median iters | median time [us] | p90 time [us] |")
    print("| --- | --- | --- | --- | --- |")
    for name, options in ABLATION.items():
        rate, iters, median, p90 = summary(run({name: Ours(model, **options)}, cases)[name])
        print(f"| {name} | {rate:.1%} | {iters:.0f} | {median:.0f} | {p90:.0f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=200, help="targets per set")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ablation", action="store_true", help="only ours, ingredient by ingredient")
    args = parser.parse_args()

    model = load_model("reach")
    rng = np.random.default_rng(args.seed)
    sets = {"global": global_cases(model, rng, args.n), "local": local_cases(model, rng, args.n)}
    if args.ablation:
        ablation(model, sets["global"])
        return
    ours, ours_value, baseline = Ours(model), Ours(model, with_value=True), Mink(model)

    print(f"tsrl.ik vs mink {version('mink')} (daqp {version('daqp')}), mujoco {mujoco.__version__}")
    print(
        f"{args.n} targets per set, seed {args.seed}; success: |dp| <= {POS_TOL} m and angle <= {ANG_TOL} rad\n"
    )
    print("| set | solver | success | median iters | median time [us] | p90 time [us] |")
    print("| --- | --- | --- | --- | --- | --- |")
    ratios = {}
    for set_name, cases in sets.items():
        solvers: dict[str, Callable[[Case], Outcome]] = {"tsrl": ours, "mink": baseline}
        if set_name == "local":
            solvers["tsrl, initial_value"] = ours_value
        results = {name: summary(outcomes) for name, outcomes in run(solvers, cases).items()}
        for name, (rate, iters, median, p90) in results.items():
            print(f"| {set_name} | {name} | {rate:.1%} | {iters:.0f} | {median:.0f} | {p90:.0f} |")
        ratios[set_name] = results["tsrl"][2] / results["mink"][2]
    print()
    for set_name, ratio in ratios.items():
        print(f"{set_name}: median time tsrl / mink = {ratio:.2f}")


if __name__ == "__main__":
    main()
