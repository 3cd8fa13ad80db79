"""Does a compiled network bring the fast preset's gradient step nearer its matrix-multiply floor?

The learner speed table's "fast preset (UTD 2)" step (speed_profile.py's setting: UR5ePickPlace-v0,
fs1, 100 demonstrations, one torch thread, 1,000 stored random-action transitions), timed with its
networks as they are and with each of them (the critics' and target critics' heads, the actor's
network) wrapped in `torch.compile` (fused LayerNorm, ReLU and bias kernels around the products),
in interleaved rounds (plain, compiled, plain, ...) on the same model.

    python studies/learner-benchmarks/speed_compile.py [--updates 100] [--rounds 3] [--mode default]

Prints the floor (learning.matmul_floor, by both clocks) and per round the updates per second of each by
the wall clock and by the process's CPU time (time.process_time: on a machine shared with other
work, the time this process ran, not the time it waited for a core), then the medians. A probe:
compiled kernels round differently, so a compiled preset would have to be screened again before it
could replace the plain one.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path
from typing import Any

from learning import matmul_floor  # type: ignore[import-not-found]
from speed_profile import fast_preset_model  # type: ignore[import-not-found]


def updates_per_second(model: Any, updates: int, batch_size: int) -> tuple[float, float]:
    """(wall, CPU time) updates per second of `updates` gradient steps."""
    wall, cpu = time.perf_counter(), time.process_time()
    model.train(gradient_steps=updates, batch_size=batch_size)
    return updates / (time.perf_counter() - wall), updates / (time.process_time() - cpu)


def print_rounds(rates: dict[str, list[tuple[float, float]]]) -> dict[str, list[float]]:
    """Prints the interleaved rounds of two variants (updates/s by the wall clock and by CPU time) and
    their medians as a table; returns the medians [wall, CPU time] by variant."""
    first, second = rates
    print(f"| round | {first}, wall | {first}, CPU time | {second}, wall | {second}, CPU time |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for index, (a, b) in enumerate(zip(rates[first], rates[second], strict=True)):
        print(f"| {index} | {a[0]:.1f} | {a[1]:.1f} | {b[0]:.1f} | {b[1]:.1f} |")
    medians = {name: [statistics.median(r[i] for r in rs) for i in (0, 1)] for name, rs in rates.items()}
    a, b = medians[first], medians[second]
    print(f"| median [updates/s] | {a[0]:.1f} | {a[1]:.1f} | {b[0]:.1f} | {b[1]:.1f} |")
    return medians


def network_slots(model: Any) -> list[tuple[Any, str | int]]:
    """(container, key) of each critic head, target critic head and the actor's network (SB3 keeps
    the heads in a plain list, the actor's network as an attribute)."""
    policy = model.policy
    slots: list[tuple[Any, str | int]] = [
        (critic.q_networks, index)
        for critic in (policy.critic, policy.critic_target)
        for index in range(len(critic.q_networks))
    ]
    return [*slots, (policy.actor, "mu")]


def get(container: Any, key: str | int) -> Any:
    return getattr(container, key) if isinstance(key, str) else container[key]


def put(container: Any, key: str | int, module: Any) -> None:
    if isinstance(key, str):
        setattr(container, key, module)
    else:
        container[key] = module


def main() -> None:
    import torch as th

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--mode", default="default", help="torch.compile's mode (default: its own)")
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    args = parser.parse_args()

    model = fast_preset_model(args.out_dir)
    batch_size = model.batch_size
    model.train(gradient_steps=args.updates // 2, batch_size=batch_size)  # untimed
    repeats = 4 * args.updates
    cpu = time.process_time()
    floor = matmul_floor(model, batch_size, repeats)
    floor_cpu = repeats / (time.process_time() - cpu)  # with its one recording step (about 1 %)
    slots = network_slots(model)
    plain = [get(c, k) for c, k in slots]
    mode = None if args.mode == "default" else args.mode
    compiled = [th.compile(module, mode=mode, dynamic=False) for module in plain]

    def use(modules: list[Any]) -> None:
        for (container, key), module in zip(slots, modules, strict=True):
            put(container, key, module)

    use(compiled)
    t0 = time.perf_counter()
    model.train(gradient_steps=args.updates // 2, batch_size=batch_size)  # compiles; untimed
    print(f"compiling and {args.updates // 2} steps: {time.perf_counter() - t0:.0f} s")
    rates: dict[str, list[tuple[float, float]]] = {"plain": [], "compiled": []}
    for _ in range(args.rounds):
        for name, modules in (("plain", plain), ("compiled", compiled)):
            use(modules)
            rates[name].append(updates_per_second(model, args.updates, batch_size))
    print(
        f"floor: {floor:.1f} updates/s by the wall clock, {floor_cpu:.1f} by CPU time (the products alone)\n"
    )
    medians = print_rounds(rates)
    p, c = medians["plain"], medians["compiled"]
    print(f"\ncompiled / plain: wall {c[0] / p[0]:.2f}, CPU time {c[1] / p[1]:.2f}")
    print(f"of the floor (CPU time): plain {p[1] / floor_cpu:.0%}, compiled {c[1] / floor_cpu:.0%}")


if __name__ == "__main__":
    main()
