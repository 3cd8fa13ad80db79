"""Deployment runtime: the Controller's compute per policy step and the servo-rate interpolation, and a
trained run's success deployed on the MuJoCo backend against `tsrl evaluate` on the same seeds.

    python benchmarks/deploy.py speed [--episodes 20]          # UR5e reach and Panda pick-and-place
    python benchmarks/deploy.py success RUN_DIR [--episodes 100] [--realtime]

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
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from tsrl.deploy.backends import MujocoBackend
from tsrl.deploy.controller import Controller, ControllerOptions
from tsrl.deploy.loop import run_episodes

TASKS = {
    "UR5e reach (fs1)": ("tsrl/UR5eReach-v0", "fs1"),
    "Panda pick-and-place (pick_phi_plus)": ("tsrl/PandaPickPlace-v0", "pick_phi_plus"),
}


def pin_to_one_core() -> int:
    """Pins this process to the first core it may run on; returns that core."""
    core = min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {core})
    return core


def untrained_export(env_id: str, obs: str, out: Path) -> Path:
    """A [256, 256] DDPG policy of `env_id` with the default settings, exported to `out`."""
    from tsrl.agents import AgentConfig, TrainConfig
    from tsrl.agents.factory import make_agent, make_vec_env
    from tsrl.deploy.export import export_policy

    cfg = TrainConfig(env_id=env_id, obs=obs, total_timesteps=1000, agent=AgentConfig(learning_starts=100))
    venv = make_vec_env(cfg)
    export_policy(make_agent(cfg, venv), venv, cfg, out)
    return out


def parts(
    controller: Controller, states: list[tuple[np.ndarray, np.ndarray, dict]], t0: float
) -> dict[str, list[float]]:
    """Seconds of each part of a policy step, timed on the given measured states in turn."""
    times: dict[str, list[float]] = {"features": [], "policy": [], "IK + safety": []}
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
        start = time.perf_counter()
        q_ik = controller._ik_step(q, np.clip(a, -1, 1), cycle, [])
        controller.limiter.set_target(q_ik, t)
        times["IK + safety"].append(time.perf_counter() - start)
    return times


def speed(episodes: int) -> None:
    core = pin_to_one_core()
    print(f"pinned to core {core}; {episodes} episodes per task on the MuJoCo backend (2 ms servo period)\n")
    header = "| task | policy steps | act p50 [ms] | act p99 [ms] | features p50 | policy p50 | IK + safety p50 | interpolate p50 [us] | interpolate p99 [us] |"
    print(header)
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    with tempfile.TemporaryDirectory() as tmp:
        for name, (env_id, obs) in TASKS.items():
            folder = untrained_export(env_id, obs, Path(tmp) / env_id.replace("/", "-"))
            backend = MujocoBackend(folder)
            controller = Controller.from_export(folder, ControllerOptions(servo_period=backend.period))
            results = run_episodes(controller, backend, list(range(episodes)))
            act = np.concatenate([r.compute_s for r in results]) * 1e3
            interp = np.concatenate([r.interpolate_s for r in results]) * 1e6
            # The parts, on states of one more episode.
            backend.connect()
            backend.reset(episodes)
            states = []
            for _ in range(200):
                s = backend.read_state()
                states.append((s.q, s.qd, s.objects))
                backend.send(s.q)
                for _ in range(20):
                    backend.wait()
            controller.reset(states[0][0], 0.0, controller.sample_goal(episodes))
            controller.act(*states[0], t=0.0)
            split = {k: np.median(v) * 1e3 for k, v in parts(controller, states, 0.04).items()}
            print(
                f"| {name} | {act.size} | {np.percentile(act, 50):.3f} | {np.percentile(act, 99):.3f} | "
                f"{split['features']:.3f} | {split['policy']:.3f} | {split['IK + safety']:.3f} | "
                f"{np.percentile(interp, 50):.1f} | {np.percentile(interp, 99):.1f} |"
            )
    print("\nparts in ms (p50); targets: act p50 <= 0.5 ms, p99 <= 2 ms; interpolate p99 <= 50 us")


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


def success(run_dir: Path, episodes: int, realtime: bool) -> None:
    from tsrl.agents import load_config
    from tsrl.agents.evaluation import eval_seeds, evaluate_run
    from tsrl.deploy.export import export_run

    cfg = load_config(run_dir)
    seeds = eval_seeds(cfg.seed, episodes)
    start = time.perf_counter()
    evaluated = evaluate_run(run_dir, episodes).result
    print(
        f"{run_dir.name}: tsrl evaluate, {episodes} episodes: success {evaluated.success_rate:.2f} ({time.perf_counter() - start:.0f} s)\n"
    )
    print("| deployment | latency [s] | joint noise [rad] | success | simulator's success | faults |")
    print("| --- | ---: | ---: | ---: | ---: | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        folder = export_run(run_dir, Path(tmp) / "export")
        probe = Controller.from_export(folder)
        noise = joint_noise_for(probe, 0.005)
        cases = [
            ("limiter (the hardware path, default)", "interpolate", False, 0.0, 0.0),
            ("limiter, --ramp", "interpolate", True, 0.0, 0.0),
            ("target held for the period (as training; no limits)", "hold", False, 0.0, 0.0),
            ("limiter, 1 period latency, 5 mm noise", "interpolate", False, probe.control_period, noise),
        ]
        for name, servo, ramp, latency, joint_noise in cases:
            backend = MujocoBackend(
                folder, realtime=realtime, latency=latency, joint_noise=joint_noise, seed=0
            )
            options = ControllerOptions(servo_period=backend.period, ramp=ramp)
            controller = Controller.from_export(folder, options)
            results = run_episodes(controller, backend, seeds, servo=servo)
            wins = np.mean([r.success for r in results])
            true = np.mean([bool(r.true_success) for r in results])
            faults: dict[str, int] = {}
            for r in results:
                for k, v in r.faults.items():
                    faults[k] = faults.get(k, 0) + v
            print(
                f"| {name} | {latency:g} | {joint_noise:.4f} | {wins:.2f} | {true:.2f} | "
                + (", ".join(f"{k} x{v}" for k, v in sorted(faults.items())) or "none")
                + " |"
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    s = sub.add_parser("speed")
    s.add_argument("--episodes", type=int, default=20)
    c = sub.add_parser("success")
    c.add_argument("run_dir", type=Path)
    c.add_argument("--episodes", type=int, default=100)
    c.add_argument("--realtime", action="store_true")
    args = parser.parse_args()
    if args.what == "speed":
        speed(args.episodes)
    else:
        success(args.run_dir, args.episodes, args.realtime)


if __name__ == "__main__":
    main()
