"""Does Adam's fused CPU kernel bring the fast preset's gradient step nearer its matrix-multiply floor,
and does it keep the numbers?

The optimizer is 18 % of the fast preset's step (speed_profile.py). tsrl's optimizers use Adam's
`foreach` implementation (one kernel per operation over all tensors); torch also has a `fused` one
(one kernel for the whole update). This probe:

1. numbers: two Adams, foreach and fused, on the fast preset's actor and critic parameter shapes,
   stepped `--steps` times with the same gradients: are the parameters equal bit for bit?
2. speed: the speed table's "fast preset (UTD 2)" step (speed_profile.py's model), timed in
   interleaved rounds with its actor's and critic's optimizers switched in place between the two
   implementations (their state and hooks kept), by the wall clock and by the process's CPU time.

    python studies/learner-benchmarks/speed_adam.py [--updates 100] [--rounds 5] [--steps 300]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import torch as th
from learning import matmul_floor  # type: ignore[import-not-found]
from speed_compile import print_rounds, updates_per_second  # type: ignore[import-not-found]
from speed_profile import fast_preset_model  # type: ignore[import-not-found]

IMPLEMENTATIONS = ("foreach", "fused")


def optimizers(model: Any) -> list[th.optim.Optimizer]:
    return [model.actor.optimizer, model.critic.optimizer]


def use(model: Any, implementation: str) -> None:
    """Switches the model's optimizers in place to Adam's `implementation` (state and hooks kept)."""
    for optimizer in optimizers(model):
        for group in optimizer.param_groups:
            group["foreach"] = implementation == "foreach"
            group["fused"] = implementation == "fused"


def same_numbers(model: Any, steps: int) -> tuple[bool, float]:
    """(bit for bit, largest difference) of foreach and fused Adam after `steps` steps from the same
    parameters (the model's actor's and critic's) with the same random gradients."""
    shapes = [p.shape for optimizer in optimizers(model) for g in optimizer.param_groups for p in g["params"]]
    start = [
        th.randn(shape, generator=th.Generator().manual_seed(index)) for index, shape in enumerate(shapes)
    ]
    finals = []
    for implementation in IMPLEMENTATIONS:
        params = [t.clone().requires_grad_(True) for t in start]
        adam = th.optim.Adam(params, lr=1e-3, **{implementation: True})  # type: ignore[arg-type]
        draws = th.Generator().manual_seed(len(shapes))
        for _ in range(steps):
            for p in params:
                p.grad = th.randn(p.shape, generator=draws)
            adam.step()
        finals.append([p.detach() for p in params])
    pairs = list(zip(*finals, strict=True))
    return all(th.equal(a, b) for a, b in pairs), max(float((a - b).abs().max()) for a, b in pairs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--updates", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300, help="Adam steps of the numbers check")
    parser.add_argument("--out-dir", type=Path, default=Path("results/benchmarks/learning"))
    args = parser.parse_args()

    model = fast_preset_model(args.out_dir)
    identical, largest = same_numbers(model, args.steps)
    print(
        f"numbers: after {args.steps} steps foreach and fused Adam are bit for bit equal: {identical} "
        f"(largest difference {largest:.3g})"
    )
    batch_size = model.batch_size
    for implementation in IMPLEMENTATIONS:  # each warmed up, untimed
        use(model, implementation)
        model.train(gradient_steps=args.updates // 2, batch_size=batch_size)
    floor = matmul_floor(model, batch_size, 4 * args.updates)
    rates: dict[str, list[tuple[float, float]]] = {name: [] for name in IMPLEMENTATIONS}
    for _ in range(args.rounds):
        for implementation in IMPLEMENTATIONS:
            use(model, implementation)
            rates[implementation].append(updates_per_second(model, args.updates, batch_size))
    print(f"floor: {floor:.1f} updates/s by the wall clock (the products alone)\n")
    medians = print_rounds(rates)
    a, b = medians["foreach"], medians["fused"]
    print(f"\nfused / foreach: wall {b[0] / a[0]:.2f}, CPU time {b[1] / a[1]:.2f}")
    print(f"of the floor (wall): foreach {a[0] / floor:.0%}, fused {b[0] / floor:.0%}")


if __name__ == "__main__":
    main()
