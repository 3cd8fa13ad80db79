"""Learning benchmark: DDPG + HER with the paper's settings; prints env steps and wall time to 50/90/95%
evaluation success, and env steps per second including learning (evaluation time excluded).

    python studies/learner-benchmarks/learning.py fetch    # Gymnasium-Robotics FetchReach-v4, the paper's agent: 3 seeds
    python studies/learner-benchmarks/learning.py speed    # learner speed: gradient steps/s of each learner option (plain SB3
                                           # DDPG + HER, feature HER, demonstrations, LayerNorm, TQC, ...)
                                           # next to the matrix-multiply floor of the same batch and networks
    python studies/learner-benchmarks/learning.py learner  # the `fast` learner preset on tsrl/UR5ePickPlace-v0 (fs1) with 100
                                           # scripted demonstrations: 5 seeds, 15,000 env steps,
                                           # 100 eval episodes; --without OPTION: one option at the paper's value
    python studies/learner-benchmarks/learning.py learner-ablation  # the learner suite, each --without OPTION and each
                                           # --screen NAME, 5 seeds each (runs reused by name): one table
    python studies/learner-benchmarks/learning.py learner-small  # the final `fast` preset (no resets) on the learner suite's
                                           # protocol beside it with smaller networks or batches (SMALL):
                                           # 5 seeds each; issue 27's 90 s target
    python studies/learner-benchmarks/learning.py speed-small  # the speed suite's rows of the fast preset and its SMALL variants
    python studies/learner-benchmarks/learning.py own-robot  # a model no one here wrote: Gymnasium-Robotics' Fetch arm,
                                           # unmodified (examples/robots/fetch_reach.toml), its own fs1 and
                                           # position action: 3 seeds, 10,000 env steps; every seed >= 90%?

The other suites are experiment files (`tsrl experiment NAME`, tables by scripts/save_experiment.py):
tsrl and her: experiments/learner-her.toml; panda: learner-panda.toml; demos: learner-demos.toml;
learner-reach, learner-obstacle, learner-pose: learner-fast-reach.toml, -obstacle.toml, -pose.toml.
The suites here vary what an experiment's [[agents]] cannot tell apart in one folder (LayerNorm,
update ratio, network and batch sizes), need a patch to run (Fetch) or time no training (speed).

Runs are ordinary tsrl run folders under --out-dir (default results/benchmarks/learning), run by
`tsrl experiment`'s runner (tsrl.experiments.pool.run_configs): a finished one is reused, an
interrupted one resumed, so the script can be stopped and started again. Delete the folder to measure
afresh. Timings assume no more parallel --jobs than free cores.

FetchReach needs Gymnasium-Robotics 1.4.2, which tsrl does not depend on: `pip install -e ".[bench]"`.
It does not run on mujoco 4 unpatched; `benchmarks/fetch_compat.register_fetch_envs` applies the small
patch, in the benchmarks only; the fetch suite runs in this process (the runner's workers would not
have the patch).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # record, fetch_compat

from fetch_compat import register_fetch_envs
from learner_tables import ABLATION_BUDGET, ablation_table, speed_render, suite_lines
from record import DATA_CSV, Measurement, add_save_argument, write_rows

from tsrl.agents import AgentConfig, HerConfig, TrainConfig
from tsrl.agents.config import NATIVE, TASK_ACTION, DemoConfig
from tsrl.experiments.milestones import save_runs

PICK = "tsrl/UR5ePickPlace-v0"
#: Per suite: (total env steps, eval every, eval episodes) where the command line gives none.
BUDGETS = {
    "learner": (15_000, 2_500, 100),
    "learner-ablation": (15_000, 2_500, 100),
    "learner-small": (15_000, 2_500, 100),
    "own-robot": (10_000, 250, 20),
}
BUDGET = (6_000, 200, 20)
#: The learner suites' demonstrations: the scripted controller's, recorded once (seed 0, successes only).
DEMO_EPISODES = 100
#: The learner suite's ablations (--without): each sets one option of the fast preset to the paper's value.
WITHOUT: dict[str, dict[str, Any]] = {
    "layer_norm": {"layer_norm": "none"},
    "utd": {"utd": 0.4},  # the paper's 40 gradient steps per update of 2 x 50 env steps
    "symmetric": {"demos": {"batch_share": 0.125}},
    "resets": {"demos": {"reset_prob": 0.0}},
}
#: The learner suite's screens (--screen NAME): other combinations tried against the target, in
#: <out>/screen-NAME/ (the ablation's runs stay where they are).
SCREENS: dict[str, dict[str, Any]] = {
    # the preset at the paper's 0.4 gradient steps per env step (the 90 s budget allows about 0.7) with
    # a reverse curriculum (RFCL): demonstration resets from the last steps, growing to the whole
    # episode over 10,000 env steps
    "curriculum-utd-0.4": {"utd": 0.4, "demos": {"reset_curriculum_steps": 10_000}},
}
#: The learner-small suite's variants of the final fast preset (LayerNorm critic, UTD 2, batch share 0.5,
#: no demonstration resets), each in <out>/small-<name>/: smaller networks or batches make each gradient
#: step cheaper, the 90 s target's bound (studies/learner-benchmarks/README.md); "final" is the preset itself.
SMALL: dict[str, dict[str, Any]] = {
    "final": {},
    "net-128": {"net_arch": (128, 128)},
    "batch-128": {"batch_size": 128},
}
#: The speed-small suite's rows (speed's labels): the fast preset and its SMALL variants.
SPEED_SMALL = ("fast preset (UTD 2)", "fast preset, networks [128, 128]", "fast preset, batch 128")
#: The suites of the command line, and those that run 5 seeds by default (the others 3).
SUITES = ("fetch", "speed", "own-robot", "learner", "learner-ablation", "learner-small", "speed-small")
FIVE_SEED_SUITES = ("learner", "learner-ablation", "learner-small")
#: Per suite, the kind of its table (learner_tables.py's suite_lines; default "wall").
SUITE_TABLES = {
    "learner": "train",
    "learner-ablation": "ablation",
    "learner-small": "small",
    "own-robot": "own_robot",
}
#: The own-robot suite's task: reach with Gymnasium-Robotics' Fetch arm (needs gymnasium-robotics).
OWN_ROBOT = Path(__file__).resolve().parents[2] / "examples" / "robots" / "fetch_reach.toml"


#: The learner suite's combination: the fast preset as first screened, with demonstration resets (the
#: ablation left them out of the preset; pinned here so that the suite stays the one measured).
SCREENED_DEMOS: dict[str, Any] = {"reset_prob": 0.5}


def learner_agent(demos: Path, without: str | None = None) -> AgentConfig:
    """The learner suite's agent: the fast preset with the demonstrations and resets 0.5 (the screened
    combination), optionally `without` one option ("layer_norm", ...) or changed as a screen says
    ("screen-<name>")."""
    change = (
        {}
        if without is None
        else SCREENS[without.removeprefix("screen-")]
        if without.startswith("screen-")
        else WITHOUT[without]
    )
    demo_cfg = DemoConfig(path=str(demos), **(SCREENED_DEMOS | change.get("demos", {})))
    return AgentConfig(learner="fast", demos=demo_cfg, **{k: v for k, v in change.items() if k != "demos"})


def configs(
    suite: str,
    seeds: list[int],
    total: int,
    eval_freq: int,
    eval_episodes: int,
    demos: Path | None = None,
    without: str | None = None,
) -> list[TrainConfig]:
    """The runs of a suite: the fast preset with demonstrations in the learner suites, else
    AgentConfig's defaults (the paper's agent)."""
    common = {"total_timesteps": total, "eval_freq": eval_freq, "eval_episodes": eval_episodes}
    if suite == "learner":
        assert demos is not None
        agent = learner_agent(demos, without)
        return [TrainConfig(env_id=PICK, obs="fs1", seed=s, agent=agent, **common) for s in seeds]
    if suite.startswith("small-"):  # one variant of the learner-small suite
        assert demos is not None
        agent = AgentConfig(
            learner="fast", demos=DemoConfig(path=str(demos)), **SMALL[suite.removeprefix("small-")]
        )
        return [TrainConfig(env_id=PICK, obs="fs1", seed=s, agent=agent, **common) for s in seeds]
    if suite == "fetch":
        agent = AgentConfig(her=HerConfig(relabel="plain"))  # Fetch has no goal-dependent features
        return [
            TrainConfig(env_id="FetchReach-v4", obs=NATIVE, action=NATIVE, seed=s, agent=agent, **common)
            for s in seeds
        ]
    if suite == "own-robot":
        from tsrl.envs import load_task

        obs = load_task(OWN_ROBOT).observation  # the task file's own (fs1 on its TCP, robot0:grip)
        return [
            TrainConfig(env_id=str(OWN_ROBOT), obs=obs, action=TASK_ACTION, seed=s, **common) for s in seeds
        ]
    raise ValueError(suite)


def run_parent(cfg: TrainConfig, out_dir: Path) -> Path:
    """The folder of a run: <out>/<fetch|pick-place|own-robot>/ (its run name below it).

    The learner suite's ablations (--without OPTION) get <out>/without-<option>/pick-place (same run names).
    """
    return out_dir / {"FetchReach-v4": "fetch", PICK: "pick-place"}.get(
        cfg.env_id, "own-robot" if cfg.is_task_file else "reach"
    )


def run_all(work: list[tuple[TrainConfig, Path]], jobs: int) -> list[Path]:
    """The run folders of `work` ((config, out dir) pairs), in order, each brought to its budget by
    `tsrl experiment`'s runner, a folder's runs `jobs` at a time; Fetch runs in this process, which
    registers its patched environments. Raises SystemExit naming a run that failed or was stopped."""
    from tsrl.experiments.pool import run_configs
    from tsrl.experiments.runner import RunOutcome, run_one

    folders: dict[Path, list[TrainConfig]] = {}
    for cfg, out_dir in work:
        folders.setdefault(run_parent(cfg, out_dir), []).append(cfg)
    outcomes: list[RunOutcome] = []
    for parent, cfgs in folders.items():
        if any(cfg.env_id.startswith("Fetch") for cfg in cfgs):
            register_fetch_envs()
            outcomes += [run_one(cfg, parent) for cfg in cfgs]
        else:
            outcomes += run_configs(cfgs, parent, jobs)
    bad = [o for o in outcomes if o.status in ("failed", "interrupted")]
    if bad:
        raise SystemExit(f"{bad[0].run_name}: {bad[0].status}: {bad[0].error}")
    return [run_parent(cfg, out_dir) / cfg.run_name for cfg, out_dir in work]


def record_benchmark_demos(out_dir: Path) -> Path:
    """The learner suites' file: 100 successful scripted pick-and-place episodes (fs1), recorded once."""
    from tsrl.agents.demo_files import save_demos, summary_line
    from tsrl.agents.demonstrators import record_demos

    path = out_dir / "demos" / f"pick-place-fs1-scripted-{DEMO_EPISODES}.npz"
    if not path.is_file():
        demos = record_demos(PICK, DEMO_EPISODES, obs="fs1", seed=0)
        print(summary_line(demos, save_demos(demos, path)), flush=True)
    return path


def speed(
    seeds: list[int],
    out_dir: Path,
    updates: int = 200,
    fill: int = 1000,
    env_steps: int = 500,
    only: tuple[str, ...] | None = None,
) -> list[dict[str, Any]]:
    """Learner speed on UR5ePickPlace-v0 (fs1), one torch thread, per learner option (or those of
    `only`, by label): gradient steps per second of `model.train` (the variant's batch, 256 but for
    its SMALL batch-128 row, `updates` steps, after one untimed call) on a buffer of
    `fill` random-action transitions, next to the matrix-multiply floor of the same update, then env
    steps per second of `model.learn` with learning (the option's gradient steps per two episodes).

    The floor: every nn.Linear of the model is hooked during one gradient step, which records each
    matrix product it runs (batch rows x in -> out, and whether gradients flow); the floor is the time
    of those products alone, run with torch.mm on this machine `updates` times back to back just
    before the timed steps (forward, and for a step with gradients the two backward products dY W
    and dY^T X), as updates per second. Plain stable-baselines3
    DDPG + its HerReplayBuffer is the first row; sbx's (JAX) DDPG with tsrl's feature HER buffer is
    added where sbx is importable (`pip install sbx-rl`; not a tsrl dependency, no floor)."""
    import time

    import torch as th
    from stable_baselines3 import DDPG, HerReplayBuffer
    from stable_baselines3.common.noise import NormalActionNoise

    from tsrl.agents import make_agent, make_vec_env

    th.set_num_threads(1)
    demos = str(record_benchmark_demos(out_dir))
    a = AgentConfig(learning_starts=fill)

    def sb3_plain(
        cfg: TrainConfig, algo: Any = DDPG, policy: Any = "MultiInputPolicy", her: Any = HerReplayBuffer
    ) -> Any:
        venv = make_vec_env(cfg)
        return algo(
            policy,
            venv,
            learning_rate=a.learning_rate,
            buffer_size=cfg.total_timesteps + 100,
            learning_starts=a.learning_starts,
            batch_size=a.batch_size,
            tau=a.tau,
            gamma=a.gamma,
            train_freq=(a.train_freq_episodes, "episode"),
            gradient_steps=a.gradient_steps,
            action_noise=NormalActionNoise(np.zeros(4), a.action_noise * np.ones(4)),
            replay_buffer_class=her,
            replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
            policy_kwargs={"net_arch": list(a.net_arch)},
            seed=cfg.seed,
            device="cpu",
        )

    def agent(**kw: Any) -> AgentConfig:
        demo_kw = kw.pop("demos", None)
        return AgentConfig(
            learning_starts=fill,
            demos=DemoConfig(path=demos, **demo_kw) if demo_kw is not None else DemoConfig(),
            **kw,
        )

    variants: dict[str, tuple[Any, AgentConfig]] = {
        "SB3 DDPG + HerReplayBuffer": (sb3_plain, a),
        "tsrl DDPG + feature HER (paper)": (None, a),
        "+ demonstrations (share 0.125, BC)": (None, agent(demos={})),
        "+ demonstrations, share 0.5": (None, agent(demos={"batch_share": 0.5})),
        "+ demonstration resets 0.5": (None, agent(demos={"reset_prob": 0.5})),
        "LayerNorm critic": (None, agent(layer_norm="critic")),
        "LayerNorm critic and actor": (None, agent(layer_norm="both")),
        "TQC + feature HER": (None, agent(algo="tqc")),
        "SAC + feature HER": (None, agent(algo="sac")),
        "fast preset (UTD 2)": (None, agent(learner="fast", demos={})),
        "fast preset, networks [128, 128]": (None, agent(learner="fast", demos={}, **SMALL["net-128"])),
        "fast preset, batch 128": (None, agent(learner="fast", demos={}, **SMALL["batch-128"])),
    }
    if only is not None:
        variants = {label: variants[label] for label in only}
    try:
        import sbx
        from sbx.td3.policies import TD3Policy

        from tsrl.agents.her import FeatureHerReplayBuffer

        variants["sbx (JAX) DDPG + feature HER"] = (
            lambda cfg: sb3_plain(cfg, sbx.DDPG, TD3Policy, FeatureHerReplayBuffer),
            a,
        )
    except ImportError:
        print("sbx not installed: its row is left out")
    rows = []
    for label, (build, agent_cfg) in variants.items():
        for seed in seeds:
            cfg = TrainConfig(
                env_id=PICK, obs="fs1", seed=seed, total_timesteps=fill + 2 * env_steps, agent=agent_cfg
            )
            model = build(cfg) if build is not None else make_agent(cfg, make_vec_env(cfg))
            model.learn(fill)  # random actions fill the buffer; no update yet
            batch = agent_cfg.batch_size
            model.train(gradient_steps=updates, batch_size=batch)  # untimed: sbx compiles here
            floor = matmul_floor(model, batch, updates) if hasattr(model.policy, "modules") else math.nan
            t0 = time.perf_counter()
            model.train(gradient_steps=updates, batch_size=batch)
            t1 = time.perf_counter()
            model.learn(env_steps, reset_num_timesteps=False)
            t2 = time.perf_counter()
            rows.append(
                {
                    "variant": label,
                    "seed": seed,
                    "updates": updates,
                    "update_s": t1 - t0,
                    "floor_updates_per_s": floor,
                    "env_steps": env_steps,
                    "learn_s": t2 - t1,
                }
            )
            print(f"{label}, seed {seed}: {updates / (t1 - t0):.1f} updates/s", flush=True)
    return rows


def matmul_floor(model: Any, batch_size: int, repeats: int) -> float:
    """Updates per second that the matrix products of one gradient step of `model` allow alone (see
    speed): the products are recorded by forward hooks on its nn.Linear layers, then run in the same
    order `repeats` times back to back (as the gradient steps are), on random operands."""
    import time

    import torch as th

    products: list[tuple[int, int, int, bool]] = []

    def record(module: th.nn.Linear, inputs: tuple[th.Tensor, ...], output: th.Tensor) -> None:
        rows = inputs[0].reshape(-1, module.in_features).shape[0]
        products.append((rows, module.in_features, module.out_features, th.is_grad_enabled()))

    linear = [m for m in model.policy.modules() if isinstance(m, th.nn.Linear)]
    hooks = [m.register_forward_hook(record) for m in linear]
    try:
        model.train(gradient_steps=1, batch_size=batch_size)
    finally:
        for hook in hooks:
            hook.remove()
    operands: dict[tuple[int, int, int], tuple[th.Tensor, th.Tensor]] = {}  # (n x k) @ (k x m)
    sequence = []
    for rows, d_in, d_out, grad in products:
        shapes = [(rows, d_in, d_out)] + ([(rows, d_out, d_in), (d_out, rows, d_in)] if grad else [])
        for n, k, m in shapes:  # backward: dX = dY W and dW = dY^T X
            if (n, k, m) not in operands:
                operands[(n, k, m)] = (th.randn(n, k), th.randn(k, m))
            sequence.append(operands[(n, k, m)])
    t0 = time.perf_counter()
    for _ in range(repeats):
        for x, w in sequence:
            th.mm(x, w)
    return repeats / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "suite",
        choices=SUITES,
    )
    parser.add_argument(
        "--without",
        choices=sorted(WITHOUT),
        default=None,
        help="learner suite: this option at the paper's value",
    )
    parser.add_argument(
        "--screen",
        choices=sorted(SCREENS),
        default=None,
        help="learner suite: the preset changed as SCREENS says",
    )
    parser.add_argument(
        "--seeds", type=int, nargs="+", default=None, help="default: 0 1 2 (learner suites: 0-4)"
    )
    parser.add_argument(
        "--total-timesteps", type=int, default=None, help="per run (default: 6000; learner suites 15000)"
    )
    parser.add_argument(
        "--eval-freq", type=int, default=None, help="env steps between evaluations (200; learner 2500)"
    )
    parser.add_argument("--eval-episodes", type=int, default=None, help="20; learner suites 100")
    parser.add_argument(
        "--jobs", type=int, default=1, help="runs in parallel (timings: no more than free cores)"
    )
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    add_save_argument(parser, "learning-SUITE")
    args = parser.parse_args()
    if args.save == "learning-SUITE":
        args.save = f"learning-{args.suite}"

    if args.suite in ("speed", "speed-small"):
        with Measurement(
            args.save,
            __file__,
            "studies/learner-benchmarks/learner_tables.py:speed_table",
            "studies/learner-benchmarks/README.md",
        ) as out:
            rows = speed(
                args.seeds or [0], args.out_dir, only=SPEED_SMALL if args.suite == "speed-small" else None
            )
            if out is not None:
                write_rows(out / DATA_CSV, rows)
        print("\n".join(["", *speed_render(rows)]))
        return
    if args.without and args.screen:
        parser.error("--without and --screen: one at a time")
    variant = args.without or (f"screen-{args.screen}" if args.screen else None)
    seeds = args.seeds or ([0, 1, 2, 3, 4] if args.suite in FIVE_SEED_SUITES else [0, 1, 2])
    total, eval_freq, eval_episodes = (
        given if given is not None else default
        for given, default in zip(
            (args.total_timesteps, args.eval_freq, args.eval_episodes),
            BUDGETS.get(args.suite, BUDGET),
            strict=True,
        )
    )
    demos = record_benchmark_demos(args.out_dir) if args.suite in FIVE_SEED_SUITES else None
    if args.suite == "learner-ablation":  # the learner suite's runs and each ablation's, in their folders
        work = [
            (cfg, args.out_dir / ablation_folder(without) if without else args.out_dir)
            for without in (None, *WITHOUT, *(f"screen-{name}" for name in SCREENS))
            for cfg in configs("learner", seeds, total, eval_freq, eval_episodes, demos, without)
        ]
        cfgs = [cfg for cfg, _ in work]
    elif args.suite == "learner-small":  # each variant's runs in <out>/small-<name>/ (same run names)
        work = [
            (cfg, args.out_dir / f"small-{name}")
            for name in SMALL
            for cfg in configs(f"small-{name}", seeds, total, eval_freq, eval_episodes, demos)
        ]
        cfgs = [cfg for cfg, _ in work]
    else:
        cfgs = configs(args.suite, seeds, total, eval_freq, eval_episodes, demos, variant)
        out_dir = args.out_dir / ablation_folder(variant) if variant else args.out_dir
        work = [(cfg, out_dir) for cfg in cfgs]
    print(
        f"{len(work)} runs, {total} env steps each, evaluation every {eval_freq} env steps "
        f"on {eval_episodes} episodes; agent: {cfgs[0].agent if args.suite.startswith('learner') else AgentConfig()}",
        flush=True,
    )
    kind = SUITE_TABLES.get(args.suite, "wall")
    doc = "docs/robots.md" if args.suite == "own-robot" else "studies/learner-benchmarks/README.md"
    table = f"studies/learner-benchmarks/learner_tables.py:table_{kind}"
    with Measurement(args.save, __file__, table, doc) as out:
        done = run_all(work, args.jobs)
        if out is not None:
            save_runs(done, out, ablation_variant if kind in ("ablation", "small") else None)
    if kind in ("ablation", "small"):
        variants: dict[str, list[Path]] = {}
        for run_dir in done:
            variants.setdefault(ablation_variant(run_dir), []).append(run_dir)
        reference = "small-final" if kind == "small" else "fast"
        print("\n".join(["", *ablation_table(variants, ABLATION_BUDGET, reference)]))
    else:
        print("\n".join(["", *suite_lines(kind, done)]))


def ablation_folder(variant: str) -> str:
    """The folder of a learner variant's runs under --out-dir: without-<option>, or screen-<name> as given."""
    return variant if variant.startswith("screen-") else f"without-{variant}"


def ablation_variant(run_dir: Path) -> str:
    """The learner ablation's variant of a run folder: "fast", "without-<option>", "screen-<name>" or
    "small-<name>" (its folder's parent)."""
    parent = run_dir.parent.parent.name
    return parent if parent.startswith(("without-", "screen-", "small-")) else "fast"


if __name__ == "__main__":
    main()
