"""Seed ensembles (issue 27, item 3): what batching K seeds' networks into one process would gain.

A study's runs differ only in their seed, so K of them could share one process and run each DDPG
gradient step for all K at once: the K actors, critics and their targets stacked along a leading axis
(`torch.func.stack_module_state`), the forward passes `torch.vmap`ped, one Adam over the stacked
tensors (Adam is elementwise, so this is K independent Adams) and one Polyak update. This script
measures that update against K separate updates of the same networks, in one process, one torch
thread, side by side (rounds interleaved), on the shapes of tsrl/UR5ePickPlace-v0 with fs1 (policy
input: observation + achieved goal + desired goal; 4 actions), batch 256, [256, 256]; and, for scale,
stable-baselines3's own DDPG `train` on the same task (the update every tsrl run makes today).

    python studies/learner-benchmarks/seed_ensembles.py                  # K = 1, 2, 4; 200 updates per timing, 5 rounds
    python studies/learner-benchmarks/seed_ensembles.py --ensembles 1 2 4 8 --save

Each printed speedup is per seed: (updates/s per seed, ensemble) / (updates/s, separate). Before the
timings, the ensemble's member k is checked against a separate copy of member k after 20 updates on
the same batches (largest parameter difference printed; float32 rounding differs in batched products).
"""

from __future__ import annotations

import argparse
import copy
import os
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("MUJOCO_GL", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))  # record: saved measurements

import torch as th
from record import DATA_CSV, Measurement, add_save_argument, read_rows, write_rows
from torch import nn
from torch.func import functional_call, stack_module_state

GAMMA, TAU, LR = 0.95, 0.05, 1e-3  # AgentConfig's defaults (the paper's)


def mlp(n_in: int, n_out: int, hidden: tuple[int, ...], tanh: bool) -> nn.Sequential:
    """An MLP as stable-baselines3 builds DDPG's actor (tanh output) and critic: ReLU hidden layers."""
    layers: list[nn.Module] = []
    for width in hidden:
        layers += [nn.Linear(n_in, width), nn.ReLU()]
        n_in = width
    layers.append(nn.Linear(n_in, n_out))
    if tanh:
        layers.append(nn.Tanh())
    return nn.Sequential(*layers)


class Learner:
    """K DDPG learners (actor, critic, their targets, two Adams): `ensemble` stacks the K into one set
    of tensors updated at once, else each is updated in turn. Batches: [K, batch, ...]."""

    def __init__(
        self,
        k: int,
        n_obs: int,
        n_act: int,
        hidden: tuple[int, ...],
        ensemble: bool,
        seed: int,
        optimizer: type[th.optim.Optimizer] = th.optim.Adam,
    ):
        th.manual_seed(seed)
        self.actors = [mlp(n_obs, n_act, hidden, tanh=True) for _ in range(k)]
        self.critics = [mlp(n_obs + n_act, 1, hidden, tanh=False) for _ in range(k)]
        self.ensemble = ensemble
        if ensemble:
            self.pa, _ = stack_module_state(self.actors)  # type: ignore[arg-type]
            self.pc, _ = stack_module_state(self.critics)  # type: ignore[arg-type]
            self.ta = {n: p.detach().clone() for n, p in self.pa.items()}
            self.tc = {n: p.detach().clone() for n, p in self.pc.items()}
            actor, critic = (
                copy.deepcopy(self.actors[0]).to("meta"),
                copy.deepcopy(self.critics[0]).to("meta"),
            )
            self.actor = th.vmap(lambda p, x: functional_call(actor, (p,), (x,)))
            self.critic = th.vmap(lambda p, x: functional_call(critic, (p,), (x,)))
            self.opt_a = optimizer(list(self.pa.values()), lr=LR)
            self.opt_c = optimizer(list(self.pc.values()), lr=LR)
        else:
            self.target_actors = [copy.deepcopy(a) for a in self.actors]
            self.target_critics = [copy.deepcopy(c) for c in self.critics]
            self.opts_a = [optimizer(a.parameters(), lr=LR) for a in self.actors]
            self.opts_c = [optimizer(c.parameters(), lr=LR) for c in self.critics]

    def update(self, obs: th.Tensor, act: th.Tensor, rew: th.Tensor, nxt: th.Tensor, done: th.Tensor) -> None:
        """One gradient step of every member on its own batch (critic, then actor, then targets)."""
        if not self.ensemble:
            for i in range(len(self.actors)):
                self._update_one(i, obs[i], act[i], rew[i], nxt[i], done[i])
            return
        with th.no_grad():
            q_next = self.critic(self.tc, th.cat([nxt, self.actor(self.ta, nxt)], -1))
            target = rew + GAMMA * (1 - done) * q_next
        q = self.critic(self.pc, th.cat([obs, act], -1))
        critic_loss = ((q - target) ** 2).mean(dim=(1, 2)).sum()  # each member's mean: its own gradient
        self.opt_c.zero_grad()
        critic_loss.backward()
        self.opt_c.step()
        actor_loss = -self.critic(self.pc, th.cat([obs, self.actor(self.pa, obs)], -1)).mean(dim=(1, 2)).sum()
        self.opt_a.zero_grad()
        actor_loss.backward()
        self.opt_a.step()
        with th.no_grad():
            for live, target_params in ((self.pa, self.ta), (self.pc, self.tc)):
                for name, p in live.items():
                    target_params[name].mul_(1 - TAU).add_(p, alpha=TAU)

    def _update_one(
        self, i: int, obs: th.Tensor, act: th.Tensor, rew: th.Tensor, nxt: th.Tensor, done: th.Tensor
    ) -> None:
        actor, critic = self.actors[i], self.critics[i]
        with th.no_grad():
            q_next = self.target_critics[i](th.cat([nxt, self.target_actors[i](nxt)], -1))
            target = rew + GAMMA * (1 - done) * q_next
        critic_loss = ((critic(th.cat([obs, act], -1)) - target) ** 2).mean()
        self.opts_c[i].zero_grad()
        critic_loss.backward()
        self.opts_c[i].step()
        actor_loss = -critic(th.cat([obs, actor(obs)], -1)).mean()
        self.opts_a[i].zero_grad()
        actor_loss.backward()
        self.opts_a[i].step()
        with th.no_grad():
            for live, target_net in ((actor, self.target_actors[i]), (critic, self.target_critics[i])):
                for p, tp in zip(live.parameters(), target_net.parameters(), strict=True):
                    tp.mul_(1 - TAU).add_(p, alpha=TAU)

    def member_parameters(self, i: int) -> list[th.Tensor]:
        """Member i's actor and critic parameters, in module order."""
        if self.ensemble:
            return [p[i] for p in (*self.pa.values(), *self.pc.values())]
        return [*self.actors[i].parameters(), *self.critics[i].parameters()]


def batches(k: int, n_obs: int, n_act: int, batch: int, n: int, seed: int) -> list[tuple[th.Tensor, ...]]:
    """n random batches [k, batch, ...] (obs, action, reward, next obs, done); rewards 0/-1 as tsrl's."""
    g = th.Generator().manual_seed(seed)
    return [
        (
            th.randn(k, batch, n_obs, generator=g),
            th.rand(k, batch, n_act, generator=g) * 2 - 1,
            -(th.rand(k, batch, 1, generator=g) < 0.8).float(),
            th.randn(k, batch, n_obs, generator=g),
            th.zeros(k, batch, 1),
        )
        for _ in range(n)
    ]


def equivalence(k: int, n_obs: int, n_act: int, hidden: tuple[int, ...], batch: int) -> float:
    """Largest |parameter difference| between the ensemble's members and separate copies after 20
    updates with SGD (Adam would scale rounding differences of near-zero gradients up to its step)."""
    ens = Learner(k, n_obs, n_act, hidden, ensemble=True, seed=0, optimizer=th.optim.SGD)
    sep = Learner(k, n_obs, n_act, hidden, ensemble=False, seed=0, optimizer=th.optim.SGD)
    for b in batches(k, n_obs, n_act, batch, 20, seed=1):
        ens.update(*b)
        sep.update(*b)
    return max(
        float((a - b).abs().max().detach())
        for i in range(k)
        for a, b in zip(ens.member_parameters(i), sep.member_parameters(i), strict=True)
    )


def updates_per_s(step: Callable[[], None], n: int) -> float:
    step()  # untimed first call
    t0 = time.perf_counter()
    for _ in range(n):
        step()
    return n / (time.perf_counter() - t0)


def sb3_updates_per_s(n: int) -> tuple[float, int, int]:
    """stable-baselines3 DDPG's `train` (tsrl's paper agent with feature HER) on UR5ePickPlace-v0 fs1,
    after 1,000 random-action env steps; (updates/s, policy input size, actions)."""
    from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env

    cfg = TrainConfig(
        env_id="tsrl/UR5ePickPlace-v0", obs="fs1", seed=0, agent=AgentConfig(learning_starts=1000)
    )
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    model.learn(1000, progress_bar=False)  # below learning_starts: stores transitions, no updates
    sizes = sum(int(space.shape[0]) for space in venv.observation_space.spaces.values())  # type: ignore[attr-defined]
    rate = updates_per_s(lambda: model.train(gradient_steps=1, batch_size=256), n)
    venv.close()
    return rate, sizes, int(venv.action_space.shape[0])  # type: ignore[index]


def cycling(learner: Learner, data: list[tuple[th.Tensor, ...]]) -> Callable[[], None]:
    """A step that updates `learner` on the batches of `data` in turn."""
    count = iter(range(10**12))
    return lambda: learner.update(*data[next(count) % len(data)])


def measure(ensembles: list[int], n: int, rounds: int, batch: int) -> list[dict[str, Any]]:
    th.set_num_threads(1)
    hidden = (256, 256)
    sb3_rates = []
    sb3_rate, n_obs, n_act = sb3_updates_per_s(n)
    sb3_rates.append(sb3_rate)
    rows = []
    for k in ensembles:
        diff = equivalence(k, n_obs, n_act, hidden, batch)
        learners = {
            mode: Learner(k, n_obs, n_act, hidden, ensemble=mode == "ensemble", seed=0)
            for mode in ("separate", "ensemble")
        }
        data = batches(k, n_obs, n_act, batch, 8, seed=2)
        rates: dict[str, list[float]] = {"separate": [], "ensemble": []}
        for _ in range(rounds):  # interleaved: both modes see the same machine load
            for mode, learner in learners.items():
                rates[mode].append(k * updates_per_s(cycling(learner, data), n // k))
        sep, ens = statistics.median(rates["separate"]), statistics.median(rates["ensemble"])
        rows.append(
            {
                "seeds_per_process": k,
                "separate_updates_per_s": sep,
                "ensemble_updates_per_s": ens,
                "speedup_per_seed": ens / sep,
                "max_param_diff_after_20": diff,
                "policy_input": n_obs,
                "actions": n_act,
                "batch": batch,
                "rounds": rounds,
                "updates_per_timing": n,
            }
        )
    sb3_rates.append(sb3_updates_per_s(n)[0])
    for row in rows:
        row["sb3_ddpg_train_updates_per_s"] = statistics.mean(sb3_rates)
    return rows


def render(rows: list[dict[str, Any]]) -> list[str]:
    """The table (markdown) from `measure`'s rows (or their CSV strings)."""
    first = rows[0]
    lines = [
        (
            f"Policy input {first['policy_input']}, {first['actions']} actions, batch {first['batch']}, "
            f"[256, 256]; median of {first['rounds']} interleaved rounds of {first['updates_per_timing']} "
            f"updates; stable-baselines3 DDPG train on the same task: "
            f"{float(first['sb3_ddpg_train_updates_per_s']):.1f} updates/s."
        ),
        "",
        "| seeds per process | separate: updates/s (all seeds) | ensemble: updates/s (all seeds) | speedup per seed | max parameter difference after 20 SGD updates |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in rows:
        lines.append(
            f"| {r['seeds_per_process']} | {float(r['separate_updates_per_s']):.1f} | "
            f"{float(r['ensemble_updates_per_s']):.1f} | {float(r['speedup_per_seed']):.2f}x | "
            f"{float(r['max_param_diff_after_20']):.1e} |"
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from the data `--save` wrote to `data_dir`."""
    return render(read_rows(data_dir / DATA_CSV))


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--ensembles", type=int, nargs="+", default=[1, 2, 4], help="seeds per process")
    parser.add_argument("--updates", type=int, default=200, help="updates per timing (all seeds together)")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--batch", type=int, default=256)
    add_save_argument(parser, "seed-ensembles")
    args = parser.parse_args()
    if min(args.ensembles) < 1 or args.updates < 1 or args.rounds < 1 or args.batch < 1:
        parser.error("--ensembles, --updates, --rounds and --batch must be >= 1")
    with Measurement(
        args.save,
        __file__,
        "studies/learner-benchmarks/seed_ensembles.py:table",
        "studies/learner-benchmarks/README.md",
    ) as out:
        rows = measure(args.ensembles, args.updates, args.rounds, args.batch)
        if out is not None:
            write_rows(out / DATA_CSV, rows)
    print("\n".join(render(rows)))


if __name__ == "__main__":
    main()
