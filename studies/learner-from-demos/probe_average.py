"""Pre-registration 40: would an averaged actor act better than the actor itself? Trains an arm's run
(run.py's configuration and demonstrations) and, at each of its evaluations, evaluates on the same
seeds the same policy with its actor's weights replaced by an average of them (weight averaging;
Nikishin et al. 2018), then puts the actor's own weights back bit for bit, so the run trains and
evaluates exactly as without the probe:

- target: TD3's target actor (the polyak average it keeps for the TD target, tau 0.005 per actor
  update);
- slow: an exponential average of the actor's weights over about `--horizon` env steps, updated
  after every update (weight 1 - exp(-env steps since the last / horizon)).

The critic, the clone and the acting gate stay the run's own. Writes a CSV per run (env steps, the
run's own evaluation, the two averaged ones) to `--curves`, and the run's row as run.py does (to
data/probes.csv with `--probe`; a killed run resumes, its slow average started anew).

    python studies/learner-from-demos/probe_average.py ARM TASK --seed S --out DIR [--horizon 2500] [--probe]
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import torch as th
from run import one_run_parser, train_arm  # type: ignore[import-not-found]

from tsrl.agents import training as training_module

AVERAGES = ("target", "slow")


@contextmanager
def actor_weights(actor: th.nn.Module, weights: Sequence[th.Tensor]) -> Iterator[None]:
    """The actor with `weights` (one per parameter) for the block, its own restored after it."""
    own = [p.detach().clone() for p in actor.parameters()]
    with th.no_grad():
        for p, w in zip(actor.parameters(), weights, strict=True):
            p.copy_(w)
    try:
        yield
    finally:
        with th.no_grad():
            for p, w in zip(actor.parameters(), own, strict=True):
                p.copy_(w)


class Averages:
    """The slow average of the actor's weights and the evaluations of both averages."""

    def __init__(self, horizon: float, curve: Path):
        self.horizon = horizon
        self.slow: list[th.Tensor] | None = None
        self.seen = 0
        self.curve = curve
        curve.parent.mkdir(parents=True, exist_ok=True)
        if not curve.is_file():  # a resumed run's rows go on below its earlier ones
            with curve.open("w", newline="") as f:
                csv.writer(f).writerow(["env_steps", "own", *AVERAGES])

    def update(self, model: Any) -> None:
        actor = model.policy.actor
        if self.slow is None:
            self.slow = [p.detach().clone() for p in actor.parameters()]
        else:
            weight = 1.0 - math.exp(-(model.num_timesteps - self.seen) / self.horizon)
            with th.no_grad():
                for s, p in zip(self.slow, actor.parameters(), strict=True):
                    s.lerp_(p.detach(), weight)
        self.seen = model.num_timesteps

    def evaluate(self, callback: Any, model: Any, own: float) -> None:
        policy = model.policy
        evaluator, normalizer = callback.session.evaluator, callback.session.normalizer
        target = list(policy.actor_target.actor.parameters())  # read only: copied into the actor
        assert self.slow is not None
        row: list[Any] = [model.num_timesteps, f"{own:.4f}"]
        for weights in (target, self.slow):
            with actor_weights(policy.actor, weights):
                row.append(f"{evaluator.evaluate(model, normalizer).success_rate:.4f}")
        with self.curve.open("a", newline="") as f:
            csv.writer(f).writerow(row)
        print("average probe:", *row, flush=True)


def attach(averages: Averages) -> None:
    """Wraps the training callback's rollout start (after each update) and evaluation."""
    callback_class = training_module._SafePointCallback
    rollout_start, evaluate = callback_class._on_rollout_start, callback_class._evaluate

    def on_rollout_start(self: Any) -> None:
        averages.update(self._model)
        rollout_start(self)

    def on_evaluate(self: Any, model: Any, step: int) -> None:
        evaluate(self, model, step)
        averages.evaluate(self, model, self.last_success)

    callback_class._on_rollout_start = on_rollout_start  # type: ignore[method-assign]
    callback_class._evaluate = on_evaluate  # type: ignore[method-assign]


def main() -> None:
    parser = one_run_parser(__doc__.splitlines()[0])
    parser.add_argument("--horizon", type=float, default=2_500.0, help="env steps of the slow average")
    parser.add_argument("--curves", type=Path, default=Path(__file__).parent / "data" / "probe-curves")
    parser.add_argument("--probe", action="store_true", help="the row to data/probes.csv (as run.py's)")
    args = parser.parse_args()
    attach(Averages(args.horizon, args.curves / f"average-{args.arm}-{args.task}-s{args.seed}.csv"))
    train_arm(args.arm, args.task, [args.seed], args.out, probe=args.probe)


if __name__ == "__main__":
    main()
