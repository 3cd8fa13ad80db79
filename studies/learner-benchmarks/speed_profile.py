"""Where the fast preset's gradient step goes, next to its matrix-multiply floor: the learner speed
table's "fast preset (UTD 2)" row (learning.py speed: UR5ePickPlace-v0, fs1, 100 demonstrations, one
torch thread, 1,000 stored random-action transitions) taken apart by torch's profiler.

    python studies/learner-benchmarks/speed_profile.py [--updates 200] [--rounds 3]

Per round: the floor (learning.matmul_floor), then `updates` gradient steps under the profiler. Prints
per round the step's time per update and, per kernel group, its own time per update, its share of
the step and its ratio to the floor, then the median over rounds. The groups: the matrix products
(aten::addmm, aten::mm: the products the floor times alone), LayerNorm and ReLU (forward and
backward), the optimizer's update (Adam's kernels, zero_grad and `Optimizer.step`'s own Python, which
includes the Python of the losses hooked into the step: the demonstrations' BC loss and the return
bound run inside `Optimizer.step`, their kernels counted in the groups above) and the rest (sampling and
relabelling, normalising, autograd, Python). The profiler slows the step by a few percent; its shares are what
this reads, the speed table's updates/s are the measure.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

from learning import PICK, matmul_floor, record_benchmark_demos  # type: ignore[import-not-found]

#: Kernel groups: the profiler's event names whose own (self) time each counts.
GROUPS = {
    "matrix products": ("aten::addmm", "aten::mm"),
    "LayerNorm": ("aten::native_layer_norm", "aten::native_layer_norm_backward"),
    "ReLU": ("aten::clamp_min", "aten::threshold_backward", "aten::relu"),
}
OPTIMIZER = "Optimizer.step#Adam.step"  # its own (self) time: Adam's Python around its kernels
ZERO_GRAD = "Optimizer.zero_grad#Adam.zero_grad"  # its total time
ADAM_KERNELS = ("aten::_foreach_", "aten::_fused_adam")  # prefixes of Adam's kernels (self time)


def profile_round(model: object, batch_size: int, updates: int) -> dict[str, float]:
    """ms per update of the step, the floor and each group (GROUPS, the optimizer, the rest)."""
    from torch.profiler import ProfilerActivity, profile

    floor_ms = 1e3 / matmul_floor(model, batch_size, updates)
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        t0 = time.perf_counter()
        model.train(gradient_steps=updates, batch_size=batch_size)  # type: ignore[attr-defined]
        step_ms = (time.perf_counter() - t0) * 1e3 / updates
    events = {e.key: e for e in prof.key_averages()}
    row = {"step": step_ms, "floor": floor_ms}
    for group, names in GROUPS.items():
        row[group] = sum(events[n].self_cpu_time_total for n in names if n in events) / 1e3 / updates
    adam_us = sum(e.self_cpu_time_total for k, e in events.items() if k.startswith(ADAM_KERNELS))
    adam_us += events[OPTIMIZER].self_cpu_time_total if OPTIMIZER in events else 0.0
    adam_us += events[ZERO_GRAD].cpu_time_total if ZERO_GRAD in events else 0.0
    row["optimizer"] = adam_us / 1e3 / updates
    row["rest"] = step_ms - sum(row[g] for g in (*GROUPS, "optimizer"))
    return row


def fast_preset_model(out_dir: Path) -> Any:
    """The speed table's "fast preset (UTD 2)" model (module docstring) on one torch thread, its
    buffer filled with 1,000 random-action transitions and no update made yet."""
    import torch as th

    from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
    from tsrl.agents.config import DemoConfig

    th.set_num_threads(1)
    fill = 1000
    agent = AgentConfig(
        learning_starts=fill, learner="fast", demos=DemoConfig(path=str(record_benchmark_demos(out_dir)))
    )
    cfg = TrainConfig(env_id=PICK, obs="fs1", seed=0, total_timesteps=fill + 1000, agent=agent)
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(fill)  # random actions fill the buffer; no update yet
    return model


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    args = parser.parse_args()

    model = fast_preset_model(args.out_dir)
    model.train(gradient_steps=args.updates, batch_size=model.batch_size)  # untimed
    rounds = [profile_round(model, model.batch_size, args.updates) for _ in range(args.rounds)]
    keys = ("step", "floor", *GROUPS, "optimizer", "rest")
    print("| round | " + " | ".join(f"{k} [ms/update]" for k in keys) + " | step of floor |")
    print("| --- |" + " ---: |" * (len(keys) + 1))
    for i, r in enumerate(rounds):
        print(f"| {i} | " + " | ".join(f"{r[k]:.2f}" for k in keys) + f" | {r['floor'] / r['step']:.0%} |")
    median = {k: statistics.median(r[k] for r in rounds) for k in keys}
    print()
    print("| part of the step (median over rounds) | ms per update | share of the step | x the floor |")
    print("| --- | ---: | ---: | ---: |")
    for k in (*GROUPS, "optimizer", "rest", "step"):
        print(
            f"| {k} | {median[k]:.2f} | {median[k] / median['step']:.0%} | {median[k] / median['floor']:.2f} |"
        )
    print(f"| the floor | {median['floor']:.2f} | {median['floor'] / median['step']:.0%} | 1.00 |")


if __name__ == "__main__":
    main()
