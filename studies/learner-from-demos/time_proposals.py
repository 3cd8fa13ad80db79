"""The wall time `--clone-proposals` adds: a fast-learner stack run of 500 env steps (bc_steps 20, the
study's 100 stack demonstrations) with K = 0 and K = 8 thinned clones, alternated twice, one torch
thread. Prints K and the seconds of `model.learn` per run (pre-registration 22 quotes them).

    OMP_NUM_THREADS=1 python studies/learner-from-demos/time_proposals.py DEMOS.npz [--proposals 8]

Wall time drifts with the machine's load: compare only the rows of one invocation.
"""

from __future__ import annotations

import argparse
import time

from stable_baselines3.common.logger import configure

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.config import DemoConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("demos", help="the stack's demonstrations (run.py's demos/PandaStack-v0-100.npz)")
    parser.add_argument("--proposals", type=int, default=8)
    args = parser.parse_args()
    for k in (0, args.proposals, 0, args.proposals):
        agent = AgentConfig(learner="fast", bc_steps=20, clone_proposals=k, demos=DemoConfig(path=args.demos))
        cfg = TrainConfig(env_id="tsrl/PandaStack-v0", seed=0, total_timesteps=500, agent=agent)
        model = make_agent(cfg, make_vec_env(cfg))
        model.set_logger(configure(None, []))
        start = time.perf_counter()
        model.learn(500)
        print(f"K = {k}: {time.perf_counter() - start:.1f} s", flush=True)


if __name__ == "__main__":
    main()
