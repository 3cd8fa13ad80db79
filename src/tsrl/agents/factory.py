"""make_env / make_vec_env / make_agent: DDPG, TD3, SAC or TQC with (feature-aware) HER, built by a factory.

Algorithms are stable-baselines3's (TQC: sb3-contrib's) own classes, never subclassed; HER enters as
the replay buffer class, LayerNorm as the policy class (tsrl.agents.learners). Observation normalisation is a VecNormalize wrapper (running mean and std of observation,
achieved and desired goal; rewards untouched) whose statistics the checkpoints save.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import sb3_contrib
import stable_baselines3
from gymnasium import spaces
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.noise import NormalActionNoise
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.torch_layers import CombinedExtractor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecNormalize

from ..envs.keys import OBS_KEYS
from ..exceptions import InvalidConfig
from .acting_gate import GatedTD3
from .action_penalty import attach_action_penalty
from .bc import BCPolicy, BehaviourCloning, DemoBatches, pretrain_actor
from .choice_distillation import attach_choice_distillation
from .config import ALGOS, BC, AgentConfig, TrainConfig, check_env_id, tsrl_env_ids
from .her import FeatureHerReplayBuffer
from .learners import policy_for
from .reference import ReferenceTD3Policy
from .return_bound import attach_return_bound

#: stable-baselines3's (or sb3-contrib's) class of each algorithm name (DDPG for "ddpg", ...).
ALGO_CLASSES: dict[str, type[OffPolicyAlgorithm]] = {
    name: getattr(stable_baselines3, name.upper(), None) or getattr(sb3_contrib, name.upper())
    for name in ALGOS
    if name != BC
} | {BC: BehaviourCloning}


def algo_class(a: AgentConfig) -> type[OffPolicyAlgorithm]:
    """The algorithm that trains a run: GatedTD3 where the clone is kept as a reference
    (tsrl.agents.acting_gate), else ALGO_CLASSES[algo]. A trained policy loads with either."""
    return GatedTD3 if a.has_reference else ALGO_CLASSES[a.algo]


class PolicyInputs(CombinedExtractor):
    """stable-baselines3's CombinedExtractor over the selected keys of the observation dict only: the
    networks see `keys` (flattened, concatenated in the Dict space's sorted key order), the rest of
    the dict (still stored, relabelled and normalised) never reaches them. With every key it is
    CombinedExtractor itself."""

    def __init__(self, observation_space: spaces.Dict, keys: tuple[str, ...]):
        super().__init__(spaces.Dict({k: observation_space[k] for k in keys}))


def make_env(cfg: TrainConfig, render_mode: str | None = None, **kwargs: Any) -> gym.Env:
    """One environment of the run (gym.make with the run's obs and action, plus `kwargs`).

    An unknown id is an error listing tsrl's environments.
    """
    if cfg.is_tsrl_env:
        check_env_id(cfg.env_id)
    elif cfg.env_id not in gym.registry:
        raise InvalidConfig(f"unknown environment {cfg.env_id!r}; accepted: {', '.join(tsrl_env_ids())}")
    kwargs = cfg.env_kwargs | kwargs
    if render_mode is not None:
        kwargs["render_mode"] = render_mode
    return gym.make(cfg.gym_id, **kwargs)


def make_vec_env(cfg: TrainConfig) -> VecEnv:
    """The training VecEnv: one Monitor-wrapped env, inside VecNormalize when cfg.agent.normalize, with
    resets to demonstration states when the demonstrations' reset_prob > 0 (tsrl.agents.demo_resets).

    VecNormalize only scales what the networks see; the replay buffer stores raw observations.
    """
    venv: VecEnv = DummyVecEnv([lambda: Monitor(_training_env(cfg))])
    if cfg.agent.normalize:
        venv = VecNormalize(
            venv,
            norm_obs=True,
            norm_reward=False,
            norm_obs_keys=list(OBS_KEYS),  # all of the dict
            clip_obs=cfg.agent.clip_obs,
            gamma=cfg.agent.gamma,
        )
    return venv


def _training_env(cfg: TrainConfig) -> gym.Env:
    env = make_env(cfg)
    demos = cfg.agent.demos
    if not demos.reset_prob:
        return env
    from .demo_files import DemoSpec, load_demos
    from .demo_resets import DemoResets, first_successes, replay_states

    assert demos.path is not None  # AgentConfig: resets need demonstrations
    replay = make_env(cfg)
    try:
        loaded = load_demos(demos.path, DemoSpec.of(env))
        states = replay_states(replay, loaded, demos.path)
    finally:
        replay.close()
    first_success = first_successes(loaded) if demos.reset_frontier_k else None
    return DemoResets(
        env,
        states,
        demos.reset_prob,
        demos.reset_curriculum_steps,
        cfg.seed,
        demos.reset_curriculum_success,
        demos.reset_frontier_k,
        first_success,
    )


def gradient_steps(cfg: TrainConfig, episode_steps: int) -> int:
    """Gradient steps per update: AgentConfig.gradient_steps, or utd x the env steps of an update."""
    a = cfg.agent
    if a.utd is None:
        return a.gradient_steps
    return max(1, round(a.utd * a.train_freq_episodes * episode_steps))


def buffer_capacity(cfg: TrainConfig, episode_steps: int) -> int:
    """Transitions the buffer is allocated for: a run never stores more than its budget plus one update."""
    return min(cfg.agent.buffer_size, cfg.total_timesteps + cfg.agent.train_freq_episodes * episode_steps)


def make_agent(cfg: TrainConfig, env: VecEnv, tensorboard_log: str | None = None) -> OffPolicyAlgorithm:
    """DDPG/TD3/SAC + HER on `env` with the settings of `cfg.agent` (see AgentConfig for each default)."""
    a: AgentConfig = cfg.agent
    n_actions = int(np.prod(env.action_space.shape or ()))  # a Box: its shape
    episode_steps = int(env.get_attr("spec")[0].max_episode_steps or 0)
    if episode_steps <= 0:
        raise InvalidConfig(f"{cfg.env_id} has no time limit; HER needs finite episodes")
    kwargs: dict[str, Any] = {
        "learning_rate": a.learning_rate,
        "buffer_size": buffer_capacity(cfg, episode_steps),
        "learning_starts": a.learning_starts,
        "batch_size": a.batch_size,
        "tau": a.tau,
        "gamma": a.gamma,
        "train_freq": (a.train_freq_episodes, "episode"),
        "gradient_steps": gradient_steps(cfg, episode_steps),
        "replay_buffer_class": FeatureHerReplayBuffer,
        "replay_buffer_kwargs": {
            "n_sampled_goal": a.her.n_sampled_goal,
            "goal_selection_strategy": a.her.strategy,
            "relabel_features": a.her.relabel == "feature",
        },
        "policy_kwargs": {
            "net_arch": list(a.net_arch),
            "features_extractor_class": PolicyInputs,
            "features_extractor_kwargs": {"keys": a.policy_inputs},
            "optimizer_kwargs": {"foreach": True},  # one kernel per update for all tensors; same numbers
        },
        "tensorboard_log": tensorboard_log,
        "seed": cfg.seed,
        "device": "cpu",
        "verbose": 0,
    }
    if a.algo == BC:
        return _make_cloner(cfg, env, kwargs)
    if a.n_step > 1:  # N-step targets (agents/her.py); default left out: saved kwargs as before
        kwargs["replay_buffer_kwargs"] |= {"n_step": a.n_step, "n_step_gamma": a.gamma}
    own_critics = a.actor_value != "first" or a.critics != 2  # TD3's policy of tsrl.agents.learners
    policy = ReferenceTD3Policy if a.has_reference else policy_for(a.algo, a.layer_norm, own_critics)  # type: ignore[arg-type]
    if a.layer_norm != "none" or a.has_reference or own_critics:
        kwargs["policy_kwargs"]["layer_norm"] = a.layer_norm
    if a.actor_value != "first":  # default left out: saved kwargs as before
        kwargs["policy_kwargs"]["actor_value"] = a.actor_value
    if a.critics != 2:
        kwargs["policy_kwargs"]["n_critics"] = a.critics
    if a.has_reference:  # the clone is made as a BC run's actor is (tsrl.agents.reference)
        kwargs["policy_kwargs"]["reference_dropout"] = a.bc_dropout
        kwargs["policy_kwargs"]["residual"] = a.residual
        kwargs["policy_kwargs"]["clone_proposals"] = a.clone_proposals
        if a.clones != 1:  # default left out: saved kwargs as before
            kwargs["policy_kwargs"]["clones"] = a.clones
    if a.algo in ("ddpg", "td3") and a.action_noise > 0:
        kwargs["action_noise"] = NormalActionNoise(np.zeros(n_actions), a.action_noise * np.ones(n_actions))
    if a.demos.active:  # demonstration buffer beside the replay, Q-filtered BC loss (agents/demos.py)
        from .demos import DemoReplayBuffer, attach_demos

        kwargs["replay_buffer_class"] = DemoReplayBuffer
        kwargs["replay_buffer_kwargs"] |= {
            "demo_share": a.demos.batch_share,
            "demo_share_end": a.demos.batch_share_end,
            "demo_share_steps": a.demos.batch_share_steps,
        }
        model = algo_class(a)(policy, env, **kwargs)
        if isinstance(model, GatedTD3):  # a resumed run's gate comes back with its settings
            model.gate.adapt_noise = a.adaptive_noise
            model.gate.clone_episodes = a.clone_episodes
        normalizer = env if isinstance(env, VecNormalize) else None
        demos = attach_demos(model, a.demos, normalizer)
        if a.starts_from_clone:  # the actor (and its reference, target) starts as BC's
            pretrain_actor(model, DemoBatches(demos, normalizer), a.bc_steps, a.batch_size)
        if normalizer is not None and a.fixed_normalizer:  # the statistics the clone was fitted under
            normalizer.training = False
    else:
        model = algo_class(a)(policy, env, **kwargs)
    attach_added_losses(model, a)
    return model


def attach_added_losses(model: OffPolicyAlgorithm, a: AgentConfig) -> None:
    """The losses that hook into the optimizers beside the algorithm's own, after the BC loss of the
    demonstrations (whose anchor scales the actor's gradient accumulated before it): on a new model and
    on one loaded to resume."""
    if a.action_l2 > 0:  # a penalty on the actor's actions (agents/action_penalty.py)
        attach_action_penalty(model, a.action_l2)
    if a.return_bound > 0:  # returns as a lower bound of the critic (agents/return_bound.py)
        attach_return_bound(model, a.return_bound, a.gamma)
    if a.distill_choice > 0:  # the choice between actor and clone cloned into the actor
        attach_choice_distillation(model, a.distill_choice)


def _make_cloner(cfg: TrainConfig, env: VecEnv, kwargs: dict[str, Any]) -> BehaviourCloning:
    """Behaviour cloning (tsrl.agents.bc) on `env` with make_agent's settings: no replay (a token
    buffer; the demonstrations are its data), no exploration noise, dropout in the actor."""
    from .demos import load_run_demos

    kwargs |= {"buffer_size": 1, "replay_buffer_class": None, "replay_buffer_kwargs": {}}
    kwargs["policy_kwargs"] |= {"bc_dropout": cfg.agent.bc_dropout}
    model = BehaviourCloning(BCPolicy, env, **kwargs)
    normalizer = env if isinstance(env, VecNormalize) else None
    model.set_demos(load_run_demos(cfg.agent.demos, env, normalizer), normalizer)
    if normalizer is not None and cfg.agent.fixed_normalizer:  # the demonstrations' statistics, as cloned
        normalizer.training = False
    return model
