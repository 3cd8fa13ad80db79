"""Learning from demonstrations (Nair et al. 2018, "Overcoming Exploration in RL with Demonstrations").

- **A demonstration buffer.** `DemoReplayBuffer` is the run's `FeatureHerReplayBuffer` with a second
  one beside it that holds the demonstration episodes (a file of tsrl.agents.demo_files), HER-relabelled
  the same feature-aware way; each minibatch draws `batch_share` of its rows from it (the last rows of
  the batch), a share that may follow a linear schedule over the env steps stored.
- **A Q-filtered behaviour-cloning loss.** `attach_bc_loss` registers a step pre-hook on the actor's
  optimizer: stable-baselines3 runs `zero_grad(); actor_loss.backward(); step()`, and the hook
  back-propagates `bc_weight * L_BC` on the demonstration rows of the batch just sampled before the
  step, so the step follows grad(actor_loss + bc_weight * L_BC) without copying any `train()`. It works
  the same for DDPG, TD3 (whose delayed actor step uses the batch of its own gradient step) and SAC
  (cloning the deterministic action tanh(mean)).

    L_BC = 1/n_demo * sum_i 1[Q(s_i, a_i) > Q(s_i, pi(s_i))] * ||pi(s_i) - a_i||^2

Q is the critic's first head (the one DDPG's and TD3's actor maximise; for TQC the mean of its first
critic's quantiles). Without `q_filter` every demonstration row counts.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
import torch as th
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.type_aliases import DictReplayBufferSamples
from stable_baselines3.common.vec_env import VecEnv, VecNormalize
from torch.utils.hooks import RemovableHandle

from ..envs.keys import OBS_KEYS
from .action_penalty import actor_action, actor_optimizer
from .config import DemoConfig
from .demo_files import Demonstrations, DemoSpec, load_demos, step_goals
from .her import FeatureHerReplayBuffer


class DemoReplayBuffer(FeatureHerReplayBuffer):
    """The replay buffer plus a demonstration buffer; `batch_share` of each batch comes from the latter.

    The demonstration buffer is a FeatureHerReplayBuffer of its own (same HER settings), filled once by
    `set_demos`; it pickles with this buffer, so checkpoints and resume keep it. The demonstration
    rows of the latest batch are `last_demo_batch` (for the BC loss). Without demonstrations, or with
    a share that rounds to 0 rows, `sample` is FeatureHerReplayBuffer's, unchanged.

    Args (beyond FeatureHerReplayBuffer's):
        demo_share: fraction of each batch drawn from the demonstrations, in [0, 1).
        demo_share_end: the fraction once `demo_share_steps` transitions have been added to the
            replay, linearly from demo_share (then held); None: demo_share throughout.
        demo_share_steps: see demo_share_end.
    """

    def __init__(
        self,
        *args: Any,
        demo_share: float = 0.125,
        demo_share_end: float | None = None,
        demo_share_steps: int = 0,
        **kwargs: Any,
    ):
        super().__init__(*args, **kwargs)
        self.demo_share = demo_share
        self.demo_share_end = demo_share_end
        self.demo_share_steps = demo_share_steps
        self.n_added = 0
        self.demo_buffer: FeatureHerReplayBuffer | None = None
        self.last_demo_batch: DictReplayBufferSamples | None = None

    def add(self, *args: Any, **kwargs: Any) -> None:
        super().add(*args, **kwargs)
        self.n_added += self.n_envs

    def share(self) -> float:
        """The demonstration share of the next batch (the schedule of the Args)."""
        end = getattr(self, "demo_share_end", None)  # None in buffers pickled before the schedule
        if end is None:
            return self.demo_share
        done = min(1.0, self.n_added / self.demo_share_steps)
        return self.demo_share + done * (end - self.demo_share)

    def set_demos(self, demos: Demonstrations) -> None:
        """Fills the demonstration buffer with the episodes of `demos` (replacing any)."""
        self.last_demo_batch = None
        if demos.n_episodes == 0:
            self.demo_buffer = None
            return
        buffer = FeatureHerReplayBuffer(
            demos.n_transitions,
            self.observation_space,
            self.action_space,
            self.env,  # type: ignore[arg-type]
            device=self.device,
            n_sampled_goal=self.n_sampled_goal,
            goal_selection_strategy=self.goal_selection_strategy.name.lower(),
            relabel_features=self.relabel_features,
            n_step=self.n_step,
            n_step_gamma=self.n_step_gamma,
        )
        if self.return_gamma is not None:
            buffer.track_returns(self.return_gamma)
        t = demos.episode_steps
        for i in range(demos.n_episodes):
            for step in range(t):
                last = step == t - 1
                buffer.add(
                    {key: getattr(demos, key)[i, step][None] for key in OBS_KEYS},
                    {key: getattr(demos, key)[i, step + 1][None] for key in OBS_KEYS},
                    demos.actions[i, step][None],
                    demos.rewards[i, step][None],
                    np.array([last]),
                    [{"TimeLimit.truncated": last}],  # time-limit ends: no terminal bootstrap cut
                )
        self.demo_buffer = buffer

    def demo_rows(self, batch_size: int) -> int:
        """Rows of a batch of `batch_size` drawn from the demonstrations."""
        return 0 if self.demo_buffer is None else round(self.share() * batch_size)

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> DictReplayBufferSamples:  # type: ignore[override]
        """(batch_size - n) replay rows, then n demonstration rows (n = demo_rows(batch_size))."""
        n = self.demo_rows(batch_size)
        if n == 0:
            self.last_demo_batch = None  # a share scheduled down to 0: no stale rows for the BC loss
            return super().sample(batch_size, env)
        replay = super().sample(batch_size - n, env)
        assert self.demo_buffer is not None
        demo = self.demo_buffer.sample(n, env)
        self.last_demo_batch = demo
        if self.last_returns is not None:
            assert self.demo_buffer.last_returns is not None  # track_returns reaches both
            self.last_returns = th.cat((self.last_returns, self.demo_buffer.last_returns))
        self.last_batch = DictReplayBufferSamples(
            observations={
                k: th.cat((replay.observations[k], demo.observations[k])) for k in replay.observations
            },
            actions=th.cat((replay.actions, demo.actions)),
            next_observations={
                k: th.cat((replay.next_observations[k], demo.next_observations[k]))
                for k in replay.next_observations
            },
            dones=th.cat((replay.dones, demo.dones)),
            rewards=th.cat((replay.rewards, demo.rewards)),
            discounts=None
            if replay.discounts is None or demo.discounts is None
            else th.cat((replay.discounts, demo.discounts)),
        )
        return self.last_batch

    def track_returns(self, gamma: float) -> None:
        """FeatureHerReplayBuffer's, for the demonstration buffer too."""
        super().track_returns(gamma)
        if self.demo_buffer is not None:
            self.demo_buffer.track_returns(gamma)

    def set_env(self, env: VecEnv) -> None:
        super().set_env(env)
        if self.demo_buffer is not None:
            self.demo_buffer.set_env(env)

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["last_demo_batch"] = None
        return state


def _first_env(venv: VecEnv) -> gym.Env:
    """The first environment inside a (VecNormalize-wrapped) DummyVecEnv."""
    while hasattr(venv, "venv"):
        venv = venv.venv
    return venv.envs[0]  # type: ignore[attr-defined]


def attach_demos(
    model: OffPolicyAlgorithm, cfg: DemoConfig, normalizer: VecNormalize | None
) -> Demonstrations:
    """Loads `cfg.path` (checked against the model's env), fills the demonstration buffer, lets the
    normaliser see the demonstration states (as OpenAI baselines' DDPG + demonstrations does) and
    attaches the BC loss. For a new model with demonstrations on (`cfg.active`); a resumed one has its
    buffer and statistics already."""
    assert cfg.active and model.env is not None
    demos = load_run_demos(cfg, model.env, normalizer)
    buffer = model.replay_buffer
    assert isinstance(buffer, DemoReplayBuffer)
    buffer.set_demos(demos)
    attach_bc_loss(model, cfg)
    return demos


def load_run_demos(cfg: DemoConfig, venv: VecEnv, normalizer: VecNormalize | None) -> Demonstrations:
    """The run's demonstration file, checked against its env (DemoSpec), its rewards recomputed under
    the env's reward scale where that is not 1, with the normaliser's statistics updated by the
    demonstration states (as OpenAI baselines' DDPG + demonstrations does)."""
    assert cfg.path is not None
    env = _first_env(venv)
    demos = load_demos(cfg.path, DemoSpec.of(env))
    base: Any = env.unwrapped  # a tsrl TaskEnv (DemoSpec.of checked it)
    if base.task.success.reward_scale != 1.0 and demos.n_episodes:  # the file stores the task's reward
        rewards = base.compute_reward(*step_goals(demos), None).reshape(demos.rewards.shape)
        demos = dataclasses.replace(demos, rewards=rewards.astype(demos.rewards.dtype))
    if normalizer is not None and demos.n_episodes:
        for key in OBS_KEYS:
            if key in normalizer.obs_rms:
                values = getattr(demos, key)
                normalizer.obs_rms[key].update(values.reshape(-1, values.shape[-1]))
    return demos


def q_filtered_bc_loss(
    actor_actions: th.Tensor, demo_actions: th.Tensor, q_values: tuple[th.Tensor, th.Tensor] | None = None
) -> tuple[th.Tensor, th.Tensor]:
    """(L_BC, mask): actions (n, k) and, for the Q filter, `q_values` (Q(s, a_demo), Q(s, pi(s))),
    each (n, 1) -> scalar mean over the n rows of mask * ||pi(s) - a||^2, and the (n,) bool mask
    (Q(s, a_demo) > Q(s, pi(s)); all True without `q_values`)."""
    if q_values is not None:
        q_demo, q_actor = q_values
        mask = (q_demo > q_actor).reshape(-1)
    else:
        mask = th.ones(demo_actions.shape[0], dtype=th.bool, device=demo_actions.device)
    return masked_squared_error(actor_actions, demo_actions, mask), mask


def masked_squared_error(actions: th.Tensor, targets: th.Tensor, mask: th.Tensor) -> th.Tensor:
    """Scalar mean over the n rows of mask * ||actions - targets||^2: actions, targets (n, k); mask (n,)."""
    return (((actions - targets) ** 2).sum(dim=1) * mask).mean()


class BCLoss:
    """Step pre-hook of the actor optimizer: back-propagates weight * L_BC on the last demo rows.

    With an `anchor` alpha (TD3+BC's form), the actor's -Q gradient already accumulated is first
    scaled by ramp * alpha / mean|Q(s, pi(s))| over the whole last batch, and L_BC is unfiltered;
    ramp is 0 for the first `warmup` env steps, then rises linearly to 1 over as many.
    Records train/bc_loss and train/q_filter_pass (share of demonstration rows cloned) in the model's
    logger (the latest gradient step's values).
    """

    def __init__(
        self,
        model: OffPolicyAlgorithm,
        weight: float,
        q_filter: bool,
        anchor: float | None = None,
        warmup: int = 0,
    ):
        self.model = model
        self.weight = weight
        self.q_filter = q_filter and anchor is None
        self.anchor = anchor
        self.warmup = warmup

    def __call__(self, optimizer: th.optim.Optimizer, args: Any, kwargs: Any) -> None:
        buffer = self.model.replay_buffer
        demo = buffer.last_demo_batch if isinstance(buffer, DemoReplayBuffer) else None
        if demo is None:
            return
        critic = self.model.critic  # type: ignore[attr-defined]
        if self.anchor is not None:
            assert isinstance(buffer, DemoReplayBuffer) and buffer.last_batch is not None
            self._scale_q_gradient(critic, buffer.last_batch.observations)
        with th.enable_grad():
            pi = actor_action(self.model, demo.observations)
            q_values = None
            if self.q_filter:  # the critic's values only where they decide
                with th.no_grad():
                    q_values = (
                        first_q(critic, demo.observations, demo.actions),
                        first_q(critic, demo.observations, pi),
                    )
            loss, mask = q_filtered_bc_loss(pi, demo.actions, q_values)
            (self.weight * loss).backward()
        self.model.logger.record("train/bc_loss", loss.item())
        self.model.logger.record("train/q_filter_pass", mask.float().mean().item())

    def _scale_q_gradient(self, critic: th.nn.Module, obs: dict[str, th.Tensor]) -> None:
        """Multiplies the actor's gradients (SB3's -mean Q, just back-propagated) by
        anchor / mean|Q(s, pi(s))| over the batch; records it as train/q_scale."""
        assert self.anchor is not None
        with th.no_grad():
            q = first_q(critic, obs, actor_action(self.model, obs))
            ramp = 1.0 if self.warmup == 0 else min(1.0, max(0.0, self.model.num_timesteps / self.warmup - 1))
            scale = ramp * self.anchor / q.abs().mean().clamp_min(1e-6)
        for group in actor_optimizer(self.model).param_groups:
            for param in group["params"]:
                if param.grad is not None:
                    param.grad.mul_(scale)
        self.model.logger.record("train/q_scale", float(scale))


def first_q(critic: th.nn.Module, obs: dict[str, th.Tensor], actions: th.Tensor) -> th.Tensor:
    """(n, 1) Q values of the critic's first head: q1_forward of stable-baselines3's critics; the
    mean of the first critic's quantiles for TQC's (whose forward gives (n, critics, quantiles))."""
    q1_forward = getattr(critic, "q1_forward", None)
    if q1_forward is not None:
        return q1_forward(obs, actions)
    return critic(obs, actions)[:, 0].mean(dim=1, keepdim=True)


def attach_bc_loss(model: OffPolicyAlgorithm, cfg: DemoConfig) -> RemovableHandle:
    """Registers BCLoss on the actor's optimizer (after creating or loading a model with
    demonstrations on, `cfg.active`)."""
    assert cfg.active
    return actor_optimizer(model).register_step_pre_hook(
        BCLoss(model, cfg.bc_weight, cfg.q_filter, cfg.bc_anchor, cfg.bc_anchor_warmup or 0)
    )
