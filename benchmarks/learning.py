"""Learning benchmark: DDPG + HER with the paper's settings; prints env steps and wall time to 50/90/95%
evaluation success, and env steps per second including learning (evaluation time excluded).

    python benchmarks/learning.py tsrl     # tsrl/UR5eReach-v0, fs1, taskspace: 3 seeds
    python benchmarks/learning.py fetch    # Gymnasium-Robotics FetchReach-v4, same agent: 3 seeds
    python benchmarks/learning.py her      # fs1 with feature-aware HER vs stable-baselines3's plain HER
    python benchmarks/learning.py all      # the three above

Runs are ordinary tsrl run folders under --out-dir (default results/benchmarks/learning): a finished
one is reused, an interrupted one resumed, so the script can be stopped and started again. Delete the
folder to measure afresh. Timings assume no more parallel --jobs than free cores.

FetchReach needs Gymnasium-Robotics 1.4.2, which tsrl does not depend on: `pip install -e ".[bench]"`.
It does not run on mujoco 4 unpatched; `fetch_compat.register_fetch_envs` (beside this file) applies
the small patch, in the benchmarks only.
"""

from __future__ import annotations

import argparse
import math
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from fetch_compat import register_fetch_envs

from tsrl.agents import AgentConfig, HerConfig, TrainConfig, read_progress
from tsrl.agents.config import NATIVE
from tsrl.agents.plotting import mean_ci95
from tsrl.agents.run_folder import latest_checkpoint, read_state

THRESHOLDS = (0.5, 0.9, 0.95)


def configs(
    suite: str, seeds: list[int], total: int, eval_freq: int, eval_episodes: int
) -> list[TrainConfig]:
    """The runs of a suite; agent settings are AgentConfig's defaults (the paper's) throughout."""
    common = {"total_timesteps": total, "eval_freq": eval_freq, "eval_episodes": eval_episodes}
    if suite == "tsrl":
        return [TrainConfig(obs="fs1", seed=s, **common) for s in seeds]
    if suite == "fetch":
        agent = AgentConfig(her=HerConfig(relabel="plain"))  # Fetch has no goal-dependent features
        return [
            TrainConfig(env_id="FetchReach-v4", obs=NATIVE, action=NATIVE, seed=s, agent=agent, **common)
            for s in seeds
        ]
    if suite == "her":
        return [
            TrainConfig(obs="fs1", seed=s, agent=AgentConfig(her=HerConfig(relabel=mode)), **common)
            for mode in ("feature", "plain")
            for s in seeds
        ]
    raise ValueError(suite)


def run_one(args: tuple[TrainConfig, Path]) -> Path:
    """Trains (or resumes, or reuses) one run in <out>/<fetch|reach>/<run name>.

    The `her` suite's feature-aware runs are the `tsrl` suite's runs (same config, same folder).
    """
    cfg, out_dir = args
    if cfg.env_id.startswith("Fetch"):
        register_fetch_envs()
    from tsrl.agents.training import resume, train

    parent = out_dir / ("fetch" if cfg.env_id.startswith("Fetch") else "reach")
    run_dir = parent / cfg.run_name
    checkpoint = latest_checkpoint(run_dir)
    if checkpoint is not None and read_state(checkpoint).env_steps >= cfg.total_timesteps:
        return run_dir
    if (run_dir / "config.json").is_file():
        return resume(run_dir, total_timesteps=cfg.total_timesteps, progress_bar=False)
    return train(cfg, parent, progress_bar=False)


def first_reaching(rows: list[dict[str, float]], threshold: float) -> tuple[float, float]:
    """(env steps, wall time s) of the first evaluation with success >= threshold; NaN if none."""
    for r in rows:
        if r["eval_success_rate"] >= threshold:
            return r["env_steps"], r["wall_time_s"]
    return math.nan, math.nan


def summarize(label: str, run_dirs: list[Path]) -> None:
    """Prints one line per seed and a mean +- 95% CI line (over the seeds that reached the level)."""
    header = " ".join(
        f"{'steps@' + str(int(t * 100)) + '%':>10} {'s@' + str(int(t * 100)) + '%':>7}" for t in THRESHOLDS
    )
    print(f"\n{label}")
    print(f"{'run':<10} {header} {'final':>6} {'steps/s':>8}")
    per_seed = []
    for run_dir in run_dirs:
        rows = read_progress(run_dir)
        reached = [first_reaching(rows, t) for t in THRESHOLDS]
        last = rows[-1]
        train_time = last["wall_time_s"] - (last.get("eval_time_s") or 0.0)
        rate = last["env_steps"] / train_time if train_time > 0 else math.nan
        per_seed.append((reached, last["eval_success_rate"], rate))
        cells = " ".join(f"{_i(s):>10} {_f(w):>7}" for s, w in reached)
        seed = run_dir.name.split("__s")[-1].split("__")[
            0
        ]  # <env>__<obs>__<action>__<algo>__s<seed>[__her-plain]
        print(f"{'seed ' + seed:<10} {cells} {last['eval_success_rate']:>6.2f} {rate:>8.1f}")
    cells = []
    for k in range(len(THRESHOLDS)):
        steps = np.array([p[0][k][0] for p in per_seed])
        walls = np.array([p[0][k][1] for p in per_seed])
        ok = np.isfinite(steps)
        if ok.any():
            (ms, hs), (mw, hw) = mean_ci95(steps[ok]), mean_ci95(walls[ok])
            note = "" if ok.all() else f"[{ok.sum()}/{len(ok)}]"
            cells.append(f"{f'{ms:.0f}±{hs:.0f}{note}':>10} {f'{mw:.0f}±{hw:.0f}':>7}")
        else:
            cells.append(f"{'never':>10} {'-':>7}")
    final = mean_ci95(np.array([p[1] for p in per_seed]))
    rate = mean_ci95(np.array([p[2] for p in per_seed]))
    print(f"{'mean±CI95':<10} {' '.join(cells)} {final[0]:>6.2f} {rate[0]:>8.1f}")


def _i(x: float) -> str:
    return "never" if not math.isfinite(x) else f"{x:.0f}"


def _f(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.0f}"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("suite", choices=["tsrl", "fetch", "her", "all"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--total-timesteps", type=int, default=6000, help="per run")
    parser.add_argument("--eval-freq", type=int, default=200, help="env steps between evaluations")
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument(
        "--jobs", type=int, default=1, help="runs in parallel (timings: no more than free cores)"
    )
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    args = parser.parse_args()

    suites = ["tsrl", "fetch", "her"] if args.suite == "all" else [args.suite]
    cfgs = [
        cfg
        for suite in suites
        for cfg in configs(suite, args.seeds, args.total_timesteps, args.eval_freq, args.eval_episodes)
    ]
    work = list(
        {(cfg.env_id, cfg.run_name): (cfg, args.out_dir) for cfg in cfgs}.values()
    )  # shared runs once
    print(
        f"{len(work)} runs, {args.total_timesteps} env steps each, evaluation every {args.eval_freq} env steps "
        f"on {args.eval_episodes} episodes; agent: {AgentConfig()}",
        flush=True,
    )
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            done = list(pool.map(run_one, work))
    else:
        done = [run_one(w) for w in work]

    groups: dict[str, list[Path]] = {}
    for (cfg, _), run_dir in zip(work, done, strict=True):
        label = f"{cfg.env_id} obs={cfg.obs} action={cfg.action} algo={cfg.agent.algo} HER={cfg.agent.her.relabel}"
        groups.setdefault(label, []).append(run_dir)
    for label, run_dirs in groups.items():
        summarize(label, run_dirs)


if __name__ == "__main__":
    main()
