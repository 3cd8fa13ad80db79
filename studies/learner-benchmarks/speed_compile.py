"""Does a compiled network bring the fast preset's gradient step nearer its matrix-multiply floor?

The learner speed table's "fast preset (UTD 2)" step (speed_profile.py's setting: UR5ePickPlace-v0,
fs1, 100 demonstrations, one torch thread, 1,000 stored random-action transitions), timed with its
networks as they are, then with each of them (the critics' and target critics' heads, the actor's
network) wrapped in `torch.compile` (fused LayerNorm, ReLU and bias kernels around the products).

    python studies/learner-benchmarks/speed_compile.py [--updates 100] [--rounds 3] [--mode default]

Prints the floor (learning.matmul_floor) and per round the updates per second of each, then the
medians and their share of the floor. A probe: compiled kernels round differently, so a compiled
preset would have to be screened again before it could replace the plain one.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

from learning import matmul_floor  # type: ignore[import-not-found]
from speed_profile import fast_preset_model  # type: ignore[import-not-found]


def updates_per_second(model: Any, updates: int, batch_size: int) -> float:
    t0 = time.perf_counter()
    model.train(gradient_steps=updates, batch_size=batch_size)
    return updates / (time.perf_counter() - t0)


def compile_networks(model: Any, mode: str) -> None:
    """Wraps each critic head, each target critic head and the actor's network in torch.compile."""
    import torch as th

    def compiled(module: Any) -> Any:
        return th.compile(module, mode=None if mode == "default" else mode, dynamic=False)

    policy = model.policy
    for critic in (policy.critic, policy.critic_target):
        for index, head in enumerate(critic.q_networks):
            critic.q_networks[index] = compiled(head)
    policy.actor.mu = compiled(policy.actor.mu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--mode", default="default", help="torch.compile's mode (default: its own)")
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    args = parser.parse_args()

    model = fast_preset_model(args.out_dir)
    batch_size = model.batch_size
    model.train(gradient_steps=args.updates // 2, batch_size=batch_size)  # untimed
    floor = matmul_floor(model, batch_size, args.updates)
    plain = [updates_per_second(model, args.updates, batch_size) for _ in range(args.rounds)]
    compile_networks(model, args.mode)
    t0 = time.perf_counter()
    model.train(gradient_steps=args.updates // 2, batch_size=batch_size)  # compiles; untimed
    print(f"compiling and {args.updates // 2} steps: {time.perf_counter() - t0:.0f} s")
    compiled = [updates_per_second(model, args.updates, batch_size) for _ in range(args.rounds)]
    print(f"floor: {floor:.1f} updates/s (the step's matrix products alone)\n")
    print("| round | plain [updates/s] | compiled [updates/s] |\n| --- | ---: | ---: |")
    for index, (p, c) in enumerate(zip(plain, compiled, strict=True)):
        print(f"| {index} | {p:.1f} | {c:.1f} |")
    p, c = statistics.median(plain), statistics.median(compiled)
    print(f"| median | {p:.1f} ({p / floor:.0%} of the floor) | {c:.1f} ({c / floor:.0%}) |")
    print(f"\ncompiled / plain: {c / p:.2f}")


if __name__ == "__main__":
    main()
