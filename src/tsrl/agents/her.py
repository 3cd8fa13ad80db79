"""FeatureHerReplayBuffer: HER that recomputes goal-dependent observation features when it relabels.

stable-baselines3's HerReplayBuffer replaces only `desired_goal` of a relabelled transition. With
task-space observations such as positionDiff(tcp, target) that leaves the observation describing the
old goal while `desired_goal` names the new one. This buffer passes every relabelled observation and
next observation through the environment's `relabel(obs, new_goal)`, vectorised over the batch, so
a relabelled transition is exactly what the environment would have emitted with the goal there. It
works on the raw stored values; normalisation (VecNormalize) is applied afterwards.

Where `track_returns(gamma)` is on (tsrl.agents.return_bound), `sample` also gives each row's
discounted return from its step to its episode's end under the row's own (relabelled) goal.

With `n_step` N > 1 (AgentConfig.n_step), each row is an N-step transition for the critic's target:
the discounted sum of the rewards of its next k = min(N, steps left in its episode) steps under the
row's goal, the (relabelled) observation k steps on, the termination of the k-th step, and
`discounts` gamma^k, which stable-baselines3's DDPG, TD3, SAC and TQC use in place of gamma (their
NStepReplayBuffer's field). Episodes cut by the time limit bootstrap from their last state.

The buffer also pickles compactly (only the filled part of its arrays), so checkpoints of a short
run stay small, and can grow when a resumed run gets a larger budget.

Pinned to stable-baselines3 2.9.2 (pyproject.toml): `_get_virtual_samples` is a private method.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3 import HerReplayBuffer
from stable_baselines3.common.type_aliases import DictReplayBufferSamples
from stable_baselines3.common.vec_env import VecEnv, VecNormalize

from ..exceptions import InvalidConfig

#: Arrays indexed by [transition, env] that hold data (the rest is configuration).
_DATA_ARRAYS = ("actions", "rewards", "dones", "timeouts", "infos", "ep_start", "ep_length")


class FeatureHerReplayBuffer(HerReplayBuffer):
    """HerReplayBuffer whose relabelled observations agree with their new goal.

    Args (beyond HerReplayBuffer's):
        relabel_features: True (default) to recompute goal-dependent features through
            `env.relabel`; False gives stable-baselines3's plain HER (for comparisons).

    The latest batch `sample` returned is `last_batch` (for losses added to the actor's, such as the
    action penalty of tsrl.agents.action_penalty), and, with `track_returns` on, its rows' returns
    `last_returns` (n, 1); neither is pickled.
    """

    return_gamma: float | None = None
    """The discount of `last_returns`; None (default): no returns are computed."""
    last_returns: th.Tensor | None = None
    n_step: int = 1
    """Steps of the critic's target per row (module docstring); 1: one-step transitions."""
    n_step_gamma: float | None = None
    """The discount of the N-step rewards and of `discounts` (the algorithm's gamma)."""

    def __init__(
        self,
        buffer_size: int,
        observation_space: spaces.Dict,
        action_space: spaces.Space,
        env: VecEnv,
        device: th.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        n_sampled_goal: int = 4,
        goal_selection_strategy: str = "future",
        copy_info_dict: bool = False,
        relabel_features: bool = True,
        n_step: int = 1,
        n_step_gamma: float | None = None,
    ):
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            env,
            device=device,
            n_envs=n_envs,
            optimize_memory_usage=optimize_memory_usage,
            handle_timeout_termination=handle_timeout_termination,
            n_sampled_goal=n_sampled_goal,
            goal_selection_strategy=goal_selection_strategy,
            copy_info_dict=copy_info_dict,
        )
        self.relabel_features = relabel_features
        if n_step > 1:  # AgentConfig checks these; a buffer built otherwise is a programming error
            assert relabel_features and n_step_gamma is not None and 0 < n_step_gamma < 1
            self.n_step, self.n_step_gamma = n_step, n_step_gamma
        if relabel_features and env is not None and not _has_relabel(env):
            raise InvalidConfig(
                "feature-aware HER needs an environment with relabel(obs, new_goal) (tsrl's environments "
                "have it); use HER relabel mode 'plain' for other environments"
            )

    def relabel(self, obs: dict[str, np.ndarray], new_goals: np.ndarray) -> dict[str, np.ndarray]:
        """obs (B, d) per key with desired_goal replaced by new_goals (B, 3) and features recomputed."""
        assert self.env is not None, "call set_env() after unpickling"
        return self.env.env_method("relabel", obs, new_goals, indices=[0])[0]

    def _get_real_samples(
        self,
        batch_indices: np.ndarray,
        env_indices: np.ndarray,
        env: VecNormalize | None = None,
    ) -> DictReplayBufferSamples:
        """HerReplayBuffer's, noting the rows' stored goals for `last_returns` and N-step rows."""
        if self._notes_goals:
            goals = self.observations["desired_goal"][batch_indices, env_indices]
            self._sampled_goals.append((batch_indices, env_indices, goals))
        return super()._get_real_samples(batch_indices, env_indices, env)

    def _get_virtual_samples(
        self,
        batch_indices: np.ndarray,
        env_indices: np.ndarray,
        env: VecNormalize | None = None,
    ) -> DictReplayBufferSamples:
        """As HerReplayBuffer's (stable-baselines3 2.9.2), plus the feature recomputation."""
        if not self.relabel_features:
            return super()._get_virtual_samples(batch_indices, env_indices, env)
        obs = {key: o[batch_indices, env_indices, :] for key, o in self.observations.items()}
        next_obs = {key: o[batch_indices, env_indices, :] for key, o in self.next_observations.items()}
        if self.copy_info_dict:
            infos = copy.deepcopy(self.infos[batch_indices, env_indices])
        else:
            infos = [{} for _ in range(len(batch_indices))]
        new_goals = self._sample_goals(batch_indices, env_indices)
        if self._notes_goals:
            self._sampled_goals.append((batch_indices, env_indices, new_goals))

        # One vectorised call for observations and next observations: same goal for both.
        n = len(batch_indices)
        both = {key: np.concatenate([obs[key], next_obs[key]]) for key in obs}
        both = self.relabel(both, np.concatenate([new_goals, new_goals]))
        obs = {key: both[key][:n] for key in obs}
        next_obs = {key: both[key][n:] for key in next_obs}

        assert self.env is not None
        # r_t = reward(next achieved goal, new desired goal), as in HerReplayBuffer.
        rewards = self.env.env_method(
            "compute_reward", next_obs["achieved_goal"], new_goals, infos, indices=[0]
        )
        rewards = rewards[0].astype(np.float32)
        obs = self._normalize_obs(obs, env)  # type: ignore[assignment]
        next_obs = self._normalize_obs(next_obs, env)  # type: ignore[assignment]
        return DictReplayBufferSamples(
            observations={key: self.to_torch(o) for key, o in obs.items()},
            actions=self.to_torch(self.actions[batch_indices, env_indices]),
            next_observations={key: self.to_torch(o) for key, o in next_obs.items()},
            dones=self.to_torch(
                self.dones[batch_indices, env_indices] * (1 - self.timeouts[batch_indices, env_indices])
            ).reshape(-1, 1),
            rewards=self.to_torch(self._normalize_reward(rewards.reshape(-1, 1), env)),
        )

    def sample(self, batch_size: int, env: VecNormalize | None = None) -> DictReplayBufferSamples:  # type: ignore[override]
        """HerReplayBuffer's sample, kept as `last_batch` (and its rows' returns as `last_returns`)."""
        self._sampled_goals: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        batch = super().sample(batch_size, env)
        if self.n_step > 1:
            batch = self._n_step_rows(batch, env)
        self.last_batch: DictReplayBufferSamples | None = batch
        self.last_returns = None
        if self.return_gamma is not None:  # rows in the order sampled: real, then relabelled
            returns = [self.returns_to_go(*rows, self.return_gamma) for rows in self._sampled_goals]
            self.last_returns = self.to_torch(np.concatenate(returns).astype(np.float32).reshape(-1, 1))
        return self.last_batch

    @property
    def _notes_goals(self) -> bool:
        """Whether sampling notes each row's goal (`_sampled_goals`: real rows, then relabelled)."""
        return self.return_gamma is not None or self.n_step > 1

    def _n_step_rows(
        self, batch: DictReplayBufferSamples, env: VecNormalize | None
    ) -> DictReplayBufferSamples:
        """`batch` (one-step rows, real then relabelled, as `_sampled_goals` notes them) as N-step rows
        (module docstring): its observations and actions, the next observation, reward and done k
        steps on, and `discounts` gamma^k (n, 1)."""
        assert self.n_step_gamma is not None
        b, e, goals = (np.concatenate(parts) for parts in zip(*self._sampled_goals, strict=True))
        n_real = len(self._sampled_goals[0][0])
        k = np.minimum(self.n_step, self._steps_left(b, e))
        rewards = self._normalize_reward(self._later_rewards(b, e, goals, k), env)
        rewards = rewards @ self.n_step_gamma ** np.arange(rewards.shape[1])
        last = (b + k - 1) % self.buffer_size  # the row whose next observation is k steps on
        next_obs = {key: value[last, e] for key, value in self.next_observations.items()}
        relabelled = self.relabel({key: value[n_real:] for key, value in next_obs.items()}, goals[n_real:])
        next_obs = {key: np.concatenate([next_obs[key][:n_real], relabelled[key]]) for key in next_obs}
        dones = self.dones[last, e] * (1 - self.timeouts[last, e])
        next_obs = self._normalize_obs(next_obs, env)  # type: ignore[assignment]
        return DictReplayBufferSamples(
            observations=batch.observations,
            actions=batch.actions,
            next_observations={key: self.to_torch(value) for key, value in next_obs.items()},
            dones=self.to_torch(dones.astype(np.float32)).reshape(-1, 1),
            rewards=self.to_torch(rewards.astype(np.float32).reshape(-1, 1)),
            discounts=self.to_torch((self.n_step_gamma**k).astype(np.float32).reshape(-1, 1)),
        )

    def track_returns(self, gamma: float) -> None:
        """From now on `sample` also sets `last_returns` with discount `gamma` in (0, 1)."""
        assert 0 < gamma < 1 and self.relabel_features  # plain HER's relabelled goals are SB3's own
        self.return_gamma = gamma

    def returns_to_go(
        self, batch_indices: np.ndarray, env_indices: np.ndarray, goals: np.ndarray, gamma: float
    ) -> np.ndarray:
        """(n,) for stored transitions (their rows in a complete episode) and goals (n, g): the
        discounted sum of the env's rewards (`compute_reward` of each later next achieved goal and
        the row's goal) from the row's step t to its episode's last step T - 1, with the last step's
        reward held after the episode (the time limit cut it, not the task):

            G_t = sum_{k=t}^{T-1} gamma^(k-t) r_k + gamma^(T-t) r_{T-1} / (1 - gamma)
        """
        n = len(batch_indices)
        if n == 0:
            return np.zeros(0)
        remaining = self._steps_left(batch_indices, env_indices)  # T - t >= 1
        rewards = self._later_rewards(batch_indices, env_indices, goals, remaining)
        last = rewards[np.arange(n), remaining - 1]
        return rewards @ gamma ** np.arange(rewards.shape[1]) + gamma**remaining * last / (1 - gamma)

    def _steps_left(self, batch_indices: np.ndarray, env_indices: np.ndarray) -> np.ndarray:
        """(n,) steps from each stored row's step t to its episode's end, T - t >= 1."""
        start = self.ep_start[batch_indices, env_indices]
        return self.ep_length[batch_indices, env_indices] - (batch_indices - start) % self.buffer_size

    def _later_rewards(
        self, batch_indices: np.ndarray, env_indices: np.ndarray, goals: np.ndarray, steps: np.ndarray
    ) -> np.ndarray:
        """(n, max(steps)) float64: row i's rewards r_t .. r_{t + steps_i - 1} (`compute_reward` of each
        later next achieved goal and the row's goal, goals (n, g)), 0 beyond; steps (n,) within the
        episode."""
        offsets = np.arange(int(steps.max()))
        row, col = np.nonzero(offsets[None, :] < steps[:, None])
        later = (batch_indices[row] + offsets[col]) % self.buffer_size
        achieved = self.next_observations["achieved_goal"][later, env_indices[row]]
        assert self.env is not None
        rewards = np.zeros((len(batch_indices), len(offsets)))
        rewards[row, col] = self.env.env_method("compute_reward", achieved, goals[row], None, indices=[0])[0]
        return rewards

    # -- compact pickling and growth ------------------------------------------------------------
    @property
    def n_stored(self) -> int:
        """Rows of the arrays that hold transitions."""
        return self.buffer_size if self.full else self.pos

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["last_batch"] = None
        state.pop("last_returns", None)
        state.pop("_sampled_goals", None)
        n = self.n_stored
        if n < self.buffer_size:  # store only the filled rows; __setstate__ pads them back
            for name in _DATA_ARRAYS:
                state[name] = state[name][:n]
            for name in ("observations", "next_observations"):
                state[name] = {key: value[:n] for key, value in state[name].items()}
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        super().__setstate__(state)
        self._pad_to(self.buffer_size)

    def grow(self, buffer_size: int) -> None:
        """Enlarges the capacity to `buffer_size` if the buffer has not wrapped around yet."""
        if buffer_size <= self.buffer_size or self.full:
            return
        self.buffer_size = buffer_size
        self._pad_to(buffer_size)

    def _pad_to(self, size: int) -> None:
        def pad(a: np.ndarray) -> np.ndarray:
            if len(a) >= size:
                return a
            out = np.zeros((size, *a.shape[1:]), dtype=a.dtype)
            out[: len(a)] = a
            return out

        for name in _DATA_ARRAYS:
            if name == "infos":
                if len(self.infos) < size:
                    extra = np.array(
                        [[{} for _ in range(self.n_envs)] for _ in range(size - len(self.infos))]
                    )
                    self.infos = np.concatenate([self.infos.reshape(-1, self.n_envs), extra])
            else:
                setattr(self, name, pad(getattr(self, name)))
        self.observations = {key: pad(value) for key, value in self.observations.items()}
        self.next_observations = {key: pad(value) for key, value in self.next_observations.items()}


def _has_relabel(env: VecEnv) -> bool:
    try:
        return callable(env.get_attr("relabel", indices=[0])[0])
    except AttributeError:
        return False
