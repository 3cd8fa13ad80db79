"""Helpers of the training tests: a seconds-long TrainConfig, damaged checkpoint files, a replay
buffer filled with random episodes, the env steps a run logged a TensorBoard scalar at, the check
that training on a demonstration dataset is training on its .npz file, a hand-built twin critic,
saved scripted reach demonstrations, the fast learner's configuration on them and random observation
batches."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch as th
from torch import nn

from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.config import DemoConfig
from tsrl.agents.demo_files import load_demos, save_demos
from tsrl.agents.demonstrators import record_demos


def tiny(algo: str = "ddpg", seed: int = 0, total: int = 200, **agent: object) -> TrainConfig:
    """Seconds of training on reach (fs1): 100 random steps, then 10 gradient steps every two
    episodes; evaluation and checkpoint every 100 env steps. `agent` overrides AgentConfig fields."""
    return TrainConfig(
        obs="fs1",
        seed=seed,
        total_timesteps=total,
        eval_freq=100,
        eval_episodes=2,
        checkpoint_freq=100,
        agent=AgentConfig(algo=algo, learning_starts=100, gradient_steps=10, batch_size=64, **agent),
    )


def cut(path: Path) -> None:
    """A file cut short, as a full disk or a kill during a copy leaves it."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


#: One way to damage each file of a checkpoint.
DAMAGE = {
    "model.zip": lambda p: p.write_bytes(b"not a zip archive"),
    "replay_buffer.pkl": cut,
    "vecnormalize.pkl": cut,
    "rng.pkl": cut,
    "state.json": cut,
}


def fill_with_random_episodes(buffer, venv, episodes: int) -> None:
    """Adds `episodes` 50-step episodes of seeded uniformly random actions to `buffer`."""
    venv.seed(0)
    venv.action_space.seed(0)
    obs = venv.reset()
    for _ in range(episodes * 50):
        action = np.array([venv.action_space.sample()])
        next_obs, reward, done, infos = venv.step(action)
        real_next = infos[0]["terminal_observation"] if done[0] else next_obs
        real_next = {k: np.asarray(v).reshape(1, -1) for k, v in real_next.items()}
        buffer.add(obs, real_next, action, reward, done, infos)
        obs = next_obs


def scalar_steps(run_dir: Path, tag: str) -> list[int]:
    """The env steps at which the run's TensorBoard files (run_dir/tb) hold the scalar `tag`."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    steps = []
    for events in (run_dir / "tb").glob("events.out.tfevents*"):
        acc = EventAccumulator(str(events))
        acc.Reload()
        if tag in acc.Tags()["scalars"]:
            steps += [e.step for e in acc.Scalars(tag)]
    return steps


def demo_buffer_and_parameters(path: Path) -> tuple[dict, dict]:
    """The demonstration buffer's contents of a tiny run on the demonstrations at `path` (any format
    load_demos reads), then its network parameters after 150 env steps (100 random, 10 gradient steps)."""
    cfg = tiny(demos=DemoConfig(path=str(path)))
    model = make_agent(cfg, make_vec_env(cfg))
    stored = model.replay_buffer.demo_buffer
    contents = {
        "observations": {k: v.copy() for k, v in stored.observations.items()},
        "next_observations": {k: v.copy() for k, v in stored.next_observations.items()},
        **{name: getattr(stored, name).copy() for name in ("actions", "rewards", "dones", "timeouts")},
        "ep_start": stored.ep_start.copy(),
        "ep_length": stored.ep_length.copy(),
    }
    model.learn(150)
    return contents, {k: v.clone() for k, v in model.policy.state_dict().items()}


def assert_trains_as_the_npz(npz: Path, other: Path) -> None:
    """Training on the dataset `other` is training on the .npz file `npz`: the same demonstration buffer
    contents, and then the same network after 150 env steps, bit for bit."""
    buffer_npz, params_npz = demo_buffer_and_parameters(npz)
    buffer_other, params_other = demo_buffer_and_parameters(other)
    assert buffer_npz.keys() == buffer_other.keys()
    for name, value in buffer_npz.items():
        if isinstance(value, dict):
            for key in value:
                np.testing.assert_array_equal(value[key], buffer_other[name][key], err_msg=f"{name}[{key}]")
        else:
            np.testing.assert_array_equal(value, buffer_other[name], err_msg=name)
    d = load_demos(npz)
    assert buffer_npz["rewards"].shape[0] == d.n_transitions
    np.testing.assert_array_equal(buffer_npz["actions"][:, 0], d.actions.reshape(-1, 3))  # the test can fail
    assert params_npz.keys() == params_other.keys()
    for key in params_npz:
        assert th.equal(params_npz[key], params_other[key]), key


class HandCritic(nn.Module):
    """Twin heads Q_i(s, a) = scale_i * (w . a) with a per-row w: the hand-built critic of the tests."""

    def __init__(self, w: th.Tensor, scales: tuple[float, float]):
        super().__init__()
        self.w, self.scales = w, scales

    def forward(self, obs: object, actions: th.Tensor) -> tuple[th.Tensor, ...]:
        value = (self.w * actions).sum(dim=1, keepdim=True)
        return tuple(scale * value for scale in self.scales)


def saved_reach_demos(tmp_path_factory: pytest.TempPathFactory, count: int) -> Path:
    """`count` scripted tsrl/UR5eReach-v0 demonstrations (fs1, recording seed 0), saved in a new folder."""
    path = tmp_path_factory.mktemp("demos") / "reach.npz"
    return save_demos(record_demos("tsrl/UR5eReach-v0", count, obs="fs1", seed=0), path)


def fast_reach(path: Path, seed: int = 0, bc_steps: int = 50, **agent: object) -> TrainConfig:
    """`--learner fast` on tsrl/UR5eReach-v0 (fs1) with the demonstrations at `path`: 400 env steps,
    batch 64, `bc_steps` cloning steps; `agent` overrides AgentConfig fields."""
    return TrainConfig(
        env_id="tsrl/UR5eReach-v0", obs="fs1", total_timesteps=400, seed=seed,
        agent=AgentConfig(
            learner="fast", batch_size=64, bc_steps=bc_steps, demos=DemoConfig(path=str(path)), **agent  # type: ignore[arg-type]
        ),
    )  # fmt: skip


def random_obs_batch(model: object, n: int, seed: int) -> dict[str, th.Tensor]:
    """n standard-normal observations (a dict of (n, dim) tensors) of `model`'s observation space."""
    rng = np.random.default_rng(seed)
    space = model.observation_space  # type: ignore[attr-defined]
    return {k: th.as_tensor(rng.normal(0, 1, (n, *space[k].shape)), dtype=th.float32) for k in space.spaces}
