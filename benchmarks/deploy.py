"""Deployment runtime: the Controller's compute per policy step and the servo-rate interpolation, and a
trained run's success deployed on the MuJoCo backend against `tsrl evaluate` on the same seeds.

    python benchmarks/deploy.py speed [--episodes 20] [--save [NAME]]   # UR5e reach and Panda pick-and-place
    python benchmarks/deploy.py success RUN_DIR [--episodes 100] [--realtime] [--trained-with CMD] [--save [NAME]]

speed: untrained [256, 256] policies (compute does not depend on the weights) exported as `tsrl export`
exports a run, deployed on the MuJoCo backend with the process pinned to one core; per policy step the
whole `act` (guards, features, policy, IK, safety) and its parts timed on the same states, and every
`interpolate` call (the backend's 2 ms servo period; targets: p50 <= 0.5 ms and p99 <= 2 ms per policy
step, interpolate p99 <= 50 us).

success: the run exported, then `tsrl evaluate`'s episodes (its seeds, its deterministic policy) and
the same seeds deployed: servo commands from the limiter (as on hardware; toward each target at once,
and with --ramp) and the policy target held for the period (as the training env steps, no limits), 0
latency; then with one control period of command latency and joint noise equivalent to 5 mm of TCP
noise per axis. The backend's clock is the simulation's, so real-time pacing
(--realtime) changes the wall time only, not one number.

--save (benchmarks/record.py) writes, for speed, one row per policy step (act and its interpolate calls,
in ns) to docs/results/benchmarks/deploy-speed/data.csv and one per timed state of the parts to
parts.csv; for success, one row per episode and deployment (and per `tsrl evaluate` episode) to
docs/results/benchmarks/deploy-success/data.csv, with the run's config.json, progress.csv and the
command that trained it (--trained-with) under run/. `speed_table` and `success_table` render
docs/deploy.md's tables from them.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows

if TYPE_CHECKING:
    from tsrl.deploy.controller import Controller
    from tsrl.deploy.loop import ServoMode

TASKS = {
    "UR5e reach (fs1)": ("tsrl/UR5eReach-v0", "fs1"),
    "Panda pick-and-place (pick_phi_plus)": ("tsrl/PandaPickPlace-v0", "pick_phi_plus"),
}
PARTS = ("features", "policy", "IK + safety")
PARTS_CSV = "parts.csv"
#: speed: states of one more episode on which the parts are timed.
PART_STATES = 200
#: success: the deployments (name, servo mode, --ramp, latency in control periods, TCP noise [m]).
CASES: tuple[tuple[str, ServoMode, bool, int, float], ...] = (
    ("limiter (the hardware path, default)", "interpolate", False, 0, 0.0),
    ("limiter, --ramp", "interpolate", True, 0, 0.0),
    ("target held for the period (as training; no limits)", "hold", False, 0, 0.0),
    ("limiter, 1 period latency, 5 mm noise", "interpolate", False, 1, 0.005),
)
EVALUATE = "tsrl evaluate"
RUN = "run"
TRAIN_COMMAND = "train_command.txt"


def ns(seconds: float) -> int:
    """Seconds as whole nanoseconds (time.perf_counter's resolution)."""
    return round(seconds * 1e9)


def pin_to_one_core() -> int:
    """Pins this process to the first core it may run on; returns that core."""
    core = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {core})
    return core


def untrained_export(env_id: str, obs: str, out: Path) -> Path:
    """A [256, 256] DDPG policy of `env_id` with the default settings, exported to `out`."""
    from stable_baselines3.common.vec_env import VecNormalize

    from tsrl.agents import AgentConfig, TrainConfig
    from tsrl.agents.factory import make_agent, make_vec_env
    from tsrl.deploy.export import export_policy

    cfg = TrainConfig(env_id=env_id, obs=obs, total_timesteps=1000, agent=AgentConfig(learning_starts=100))
    venv = make_vec_env(cfg)
    assert isinstance(venv, VecNormalize)  # the default config normalises
    export_policy(make_agent(cfg, venv), venv, cfg, out)
    return out


def parts(
    controller: Controller, states: list[tuple[np.ndarray, np.ndarray, dict]], t0: float
) -> dict[str, list[float]]:
    """Seconds of each part of a policy step (PARTS), timed on the given measured states in turn."""
    times: dict[str, list[float]] = {part: [] for part in PARTS}
    T = controller.control_period
    for k, (q, qd, objects) in enumerate(states):
        t = t0 + k * T
        start = time.perf_counter()
        obs, achieved, desired = controller._features(q, qd, objects)
        times["features"].append(time.perf_counter() - start)
        start = time.perf_counter()
        a = controller.policy({"observation": obs, "achieved_goal": achieved, "desired_goal": desired})
        times["policy"].append(time.perf_counter() - start)
        cycle = controller.last
        assert cycle is not None
        start = time.perf_counter()
        q_ik = controller._ik_step(q, np.clip(a, -1, 1), cycle, [])
        controller.limiter.set_target(q_ik, t)
        times["IK + safety"].append(time.perf_counter() - start)
    return times


def measure_speed(episodes: int) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Rows of every policy step (task, episode, step, act_ns, interpolate_ns: the step's interpolate
    calls, space-separated) and of every state the parts are timed on (task, state, one column per part
    in ns), per task of TASKS."""
    from tsrl.deploy.backends import MujocoBackend
    from tsrl.deploy.controller import Controller, ControllerOptions
    from tsrl.deploy.loop import run_episodes

    steps: list[dict[str, Any]] = []
    timed: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, (env_id, obs) in TASKS.items():
            folder = untrained_export(env_id, obs, Path(tmp) / env_id.replace("/", "-"))
            backend = MujocoBackend(folder)
            controller = Controller.from_export(folder, ControllerOptions(servo_period=backend.period))
            ticks = round(controller.control_period / backend.period)
            for episode, r in enumerate(run_episodes(controller, backend, list(range(episodes)))):
                for step, act in enumerate(r.compute_s):
                    calls = r.interpolate_s[step * ticks : (step + 1) * ticks]
                    steps.append(
                        {
                            "task": name,
                            "episode": episode,
                            "step": step,
                            "act_ns": ns(act),
                            "interpolate_ns": " ".join(str(ns(s)) for s in calls),
                        }
                    )
            # The parts, on states of one more episode.
            backend.connect()
            backend.reset(episodes)
            states = []
            for _ in range(PART_STATES):
                s = backend.read_state()
                states.append((s.q, s.qd, s.objects))
                backend.send(s.q)
                for _ in range(ticks):
                    backend.wait()
            controller.reset(states[0][0], 0.0, controller.sample_goal(episodes))
            controller.act(*states[0], t=0.0)
            split = parts(controller, states, controller.control_period)
            for k in range(len(states)):
                timed.append({"task": name, "state": k} | {f"{p}_ns": ns(split[p][k]) for p in PARTS})
    return steps, timed


def render_speed(steps: list[dict[str, Any]], timed: list[dict[str, Any]]) -> list[str]:
    """docs/deploy.md's speed table (markdown lines) from `measure_speed`'s rows (or their CSV strings):
    act percentiles in ms, the parts' medians in ms, interpolate percentiles in us."""
    lines = [
        (
            "| task | policy steps | act p50 [ms] | act p99 [ms] | features p50 | policy p50 | IK + safety p50 "
            "| interpolate calls | interpolate p50 [us] | interpolate p99 [us] |"
        ),
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name in dict.fromkeys(r["task"] for r in steps):
        act = np.array([int(r["act_ns"]) for r in steps if r["task"] == name]) * 1e-6
        interp = np.array(
            [int(t) for r in steps if r["task"] == name for t in str(r["interpolate_ns"]).split()]
        )
        interp = interp * 1e-3
        split = [np.median([int(r[f"{p}_ns"]) for r in timed if r["task"] == name]) * 1e-6 for p in PARTS]
        lines.append(
            f"| {name} | {act.size} | {np.percentile(act, 50):.3f} | {np.percentile(act, 99):.3f} | "
            + " | ".join(f"{x:.3f}" for x in split)
            + f" | {interp.size} | {np.percentile(interp, 50):.1f} | {np.percentile(interp, 99):.1f} |"
        )
    return lines


def speed_table(data_dir: Path) -> list[str]:
    """The speed table from the data `speed --save` wrote to `data_dir`."""
    return render_speed(read_rows(data_dir / DATA_CSV), read_rows(data_dir / PARTS_CSV))


def joint_noise_for(controller: Controller, tcp_noise: float) -> float:
    """Joint noise [rad] that moves the TCP by `tcp_noise` [m] (std per axis) at the home pose."""
    import mujoco

    model, data = controller.model, controller.data
    controller.env.bound_robot.reset_to_home(model, data)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jac = np.zeros((3, model.nv))
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, controller.contract["robot"]["tcp"]["frame"])
    mujoco.mj_jacSite(model, data, jac, None, site)
    J = jac[:, controller._dofs]
    return float(tcp_noise / np.sqrt(np.trace(J @ J.T) / 3))


def measure_success(run_dir: Path, episodes: int, realtime: bool) -> tuple[list[dict[str, Any]], float]:
    """One row per episode: `tsrl evaluate`'s (case EVALUATE: its policy on one seed at a time) and each
    deployment's of CASES on the same seeds (case, latency [s], joint noise [rad], seed, success, the
    simulator's success, final distance [m], faults as "name:count;..."); and `tsrl evaluate`'s success
    rate over all the seeds at once (as the command runs them)."""
    from tsrl.agents.evaluation import eval_seeds, evaluate_policy, evaluate_run, load_run_policy
    from tsrl.agents.transfer import eval_task
    from tsrl.deploy.backends import MujocoBackend
    from tsrl.deploy.controller import Controller, ControllerOptions
    from tsrl.deploy.export import export_run
    from tsrl.deploy.loop import run_episodes

    start = time.perf_counter()
    batched = evaluate_run(run_dir, episodes).result.success_rate
    cfg, model, normalizer, _ = load_run_policy(run_dir)
    seeds = eval_seeds(cfg.seed, episodes)
    task = eval_task(cfg)
    rows: list[dict[str, Any]] = []
    for seed in seeds:
        result = evaluate_policy(cfg, model, normalizer, task, [seed])
        rows.append(
            {
                "case": EVALUATE,
                "latency_s": 0.0,
                "joint_noise_rad": 0.0,
                "seed": seed,
                "success": int(result.success_rate == 1.0),
                "true_success": "",
                "distance_m": result.mean_final_distance,
                "faults": "",
            }
        )
    print(
        f"{run_dir.name}: tsrl evaluate, {episodes} episodes: {batched:.2f} ({time.perf_counter() - start:.0f} s)"
    )
    with tempfile.TemporaryDirectory() as tmp:
        folder = export_run(run_dir, Path(tmp) / "export")
        probe = Controller.from_export(folder)
        for name, servo, ramp, periods, tcp_noise in CASES:
            latency = periods * probe.control_period
            joint_noise = joint_noise_for(probe, tcp_noise) if tcp_noise else 0.0
            backend = MujocoBackend(
                folder, realtime=realtime, latency=latency, joint_noise=joint_noise, seed=0
            )
            controller = Controller.from_export(
                folder, ControllerOptions(servo_period=backend.period, ramp=ramp)
            )
            for r in run_episodes(controller, backend, seeds, servo=servo):
                rows.append(
                    {
                        "case": name,
                        "latency_s": latency,
                        "joint_noise_rad": joint_noise,
                        "seed": r.seed,
                        "success": int(r.success),
                        "true_success": int(bool(r.true_success)),
                        "distance_m": r.distance,
                        "faults": ";".join(f"{k}:{v}" for k, v in sorted(r.faults.items())),
                    }
                )
            print(render_success(rows, {})[-1], flush=True)
    return rows, batched


def describe_run(config: dict[str, Any]) -> str:
    """The run in a few words from its config.json: algorithm, observation, task, seed, budget, inputs."""
    agent = config["agent"]
    return (
        f"{agent['algo'].upper()}, {config['obs']}, `{config['env_id']}`, seed {config['seed']}, "
        f"{config['total_timesteps']:,} env steps, policy inputs {', '.join(agent['policy_inputs'])}, "
        f"HER {agent['her']['strategy']} k={agent['her']['n_sampled_goal']}"
    )


def render_success(rows: list[dict[str, Any]], run: dict[str, Any]) -> list[str]:
    """docs/deploy.md's success table (markdown lines) from `measure_success`'s rows (or their CSV
    strings), with a line naming the run (`run`: its config.json and the command that trained it)."""
    lines = []
    if run:
        lines += [f"Run: {describe_run(run['config'])}; trained with `{run['command']}`.", ""]
    evaluated = [int(r["success"]) for r in rows if r["case"] == EVALUATE]
    lines += [
        f"`tsrl evaluate` on the same seeds: {sum(evaluated)}/{len(evaluated)}.",
        "",
        "| deployment | latency [s] | joint noise [rad] | episodes | success | simulator's success | faults |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for case in dict.fromkeys(r["case"] for r in rows if r["case"] != EVALUATE):
        mine = [r for r in rows if r["case"] == case]
        faults: dict[str, int] = {}
        for r in mine:
            for item in filter(None, str(r["faults"]).split(";")):
                k, v = item.split(":")
                faults[k] = faults.get(k, 0) + int(v)
        lines.append(
            f"| {case} | {float(mine[0]['latency_s']):g} | {float(mine[0]['joint_noise_rad']):.4f} | {len(mine)} | "
            f"{np.mean([int(r['success']) for r in mine]):.2f} | {np.mean([int(r['true_success']) for r in mine]):.2f} | "
            + (", ".join(f"{k} x{v}" for k, v in sorted(faults.items())) or "none")
            + " |"
        )
    return lines


def success_table(data_dir: Path) -> list[str]:
    """The success table from the data `success --save` wrote to `data_dir`."""
    run = {
        "config": json.loads((data_dir / RUN / "config.json").read_text()),
        "command": (data_dir / RUN / TRAIN_COMMAND).read_text().strip(),
    }
    return render_success(read_rows(data_dir / DATA_CSV), run)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    s = sub.add_parser("speed")
    s.add_argument("--episodes", type=int, default=20)
    add_save_argument(s, "deploy-speed")
    c = sub.add_parser("success")
    c.add_argument("run_dir", type=Path)
    c.add_argument("--episodes", type=int, default=100)
    c.add_argument("--realtime", action="store_true")
    c.add_argument(
        "--trained-with",
        metavar="CMD",
        default=None,
        help="the command that trained RUN_DIR (needed with --save)",
    )
    add_save_argument(c, "deploy-success")
    args = parser.parse_args()
    if args.what == "speed":
        with Measurement(args.save, __file__, "speed_table", "docs/deploy.md") as out:
            core = pin_to_one_core()
            print(
                f"pinned to core {core}; {args.episodes} episodes per task on the MuJoCo backend (2 ms servo period)"
            )
            steps, timed = measure_speed(args.episodes)
            if out is not None:
                write_rows(out / DATA_CSV, steps)
                write_rows(out / PARTS_CSV, timed)
        print("\n".join(render_speed(steps, timed)))
        print("\nparts in ms (p50); targets: act p50 <= 0.5 ms, p99 <= 2 ms; interpolate p99 <= 50 us")
        return
    if args.save is not None and not args.trained_with:
        parser.error("success --save needs --trained-with CMD (the command that trained RUN_DIR)")
    with Measurement(args.save, __file__, "success_table", "docs/deploy.md") as out:
        rows, batched = measure_success(args.run_dir, args.episodes, args.realtime)
        evaluated = np.mean([int(r["success"]) for r in rows if r["case"] == EVALUATE])
        if evaluated != batched:
            raise SystemExit(
                f"tsrl evaluate's success {batched} differs from its episodes one at a time ({evaluated})"
            )
        run: dict[str, Any] = {}
        if out is not None:
            write_rows(out / DATA_CSV, rows)
            (out / RUN).mkdir(exist_ok=True)
            for name in ("config.json", "progress.csv"):
                shutil.copy2(args.run_dir / name, out / RUN / name)
            (out / RUN / TRAIN_COMMAND).write_text(args.trained_with + "\n")
            run = {
                "config": json.loads((out / RUN / "config.json").read_text()),
                "command": args.trained_with,
            }
    print("\n".join(render_success(rows, run)))


if __name__ == "__main__":
    main()
