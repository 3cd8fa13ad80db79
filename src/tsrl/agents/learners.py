"""Learner options that need their own networks: LayerNorm actor and critic MLPs (RLPD, Ball et al. 2023).

stable-baselines3 2.9.2's actors and critics build their MLPs with `create_mlp` and no way to pass
normalisation layers through policy_kwargs, so the policies here are the algorithms' own
MultiInputPolicy with `make_actor` / `make_critic` extended: the networks they build are taken as they
are and a LayerNorm (with its affine weights) inserted after each hidden Linear layer, before its
activation. The Linear layers are the very modules SB3 created (same initialisation, same random
draws); only the LayerNorms are new. The policy classes are module-level, so saved models load
with them (stable-baselines3 stores the class and `policy_kwargs`, `layer_norm` among them).

    layer_norm = "critic": every critic (and target critic) network; "both": the actor's too.

TD3's policy also takes `actor_value` (AgentConfig.actor_value): with "lowest" its critics are
`LowestHeadCritic`s, whose `q1_forward` (the value stable-baselines3's TD3 actor loss climbs) is the
lowest of the heads instead of the first. With `n_critics` above 2 (AgentConfig.critics) the heads
beyond the twin come from their own generator, so the actor, the twin heads and the fast learner's
clone start as in the run without them.
"""

from __future__ import annotations

from typing import Any

import sb3_contrib.tqc.policies as tqc_policies
import stable_baselines3.sac.policies as sac_policies
import stable_baselines3.td3.policies as td3_policies
import torch as th
from stable_baselines3.common.policies import BasePolicy, ContinuousCritic
from stable_baselines3.common.type_aliases import PyTorchObs
from torch import nn

from .own_draws import own_draws

#: layer_norm values that normalise the critic / the actor (AgentConfig.layer_norm).
NORMALISED_CRITIC = ("critic", "both")
NORMALISED_ACTOR = ("both",)


def with_layer_norm(mlp: nn.Sequential, n_hidden: int) -> nn.Sequential:
    """`mlp` (create_mlp's layers) with nn.LayerNorm(width) after each of its first `n_hidden`
    Linear layers (the hidden ones); the output layer and its squashing stay as they are."""
    layers: list[nn.Module] = []
    seen = 0
    for layer in mlp:
        layers.append(layer)
        if isinstance(layer, nn.Linear) and seen < n_hidden:
            layers.append(nn.LayerNorm(layer.out_features))
            seen += 1
    return nn.Sequential(*layers)


def _normalise_critic(critic: nn.Module, n_hidden: int) -> None:
    """Replaces each of the critic's q_networks (SB3's ContinuousCritic, sb3-contrib's TQC Critic)."""
    q_networks: list[nn.Module] = critic.q_networks  # type: ignore[assignment]
    for idx, q_net in enumerate(q_networks):
        assert isinstance(q_net, nn.Sequential)
        q_networks[idx] = with_layer_norm(q_net, n_hidden)
        critic.add_module(f"qf{idx}", q_networks[idx])


class _LayerNormMixin:
    """make_actor / make_critic of the policy it precedes in the MRO, with LayerNorm added."""

    net_arch: Any
    actor_kwargs: dict[str, Any]
    critic_kwargs: dict[str, Any]

    def __init__(self, *args: Any, layer_norm: str = "critic", **kwargs: Any):
        # Set before BasePolicy.__init__, which builds the networks (torch allows plain attributes).
        object.__setattr__(self, "layer_norm", layer_norm)
        super().__init__(*args, **kwargs)

    def make_actor(self, features_extractor: Any = None) -> Any:
        actor = super().make_actor(features_extractor)  # type: ignore[misc]
        if self.layer_norm in NORMALISED_ACTOR:  # type: ignore[attr-defined]
            n_hidden = len(self.actor_kwargs["net_arch"])
            if hasattr(actor, "mu") and isinstance(actor.mu, nn.Sequential):  # DDPG / TD3
                actor.mu = with_layer_norm(actor.mu, n_hidden)
            else:  # SAC / TQC: the hidden layers, then the mean and log-std heads
                actor.latent_pi = with_layer_norm(actor.latent_pi, n_hidden)
        return actor

    def make_critic(self, features_extractor: Any = None) -> Any:
        critic = super().make_critic(features_extractor)  # type: ignore[misc]
        if self.layer_norm in NORMALISED_CRITIC:  # type: ignore[attr-defined]
            _normalise_critic(critic, len(self.critic_kwargs["net_arch"]))
        return critic

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data: dict[str, Any] = super()._get_constructor_parameters()  # type: ignore[misc]
        data["layer_norm"] = self.layer_norm  # type: ignore[attr-defined]
        return data


#: TD3's critic heads, drawn as stable-baselines3 draws them; AgentConfig.critics adds further ones.
TWIN = 2
#: Added to the run's torch seed for the generator of the heads beyond TWIN.
FURTHER_HEADS_SEED = 7919


class LowestHeadCritic(ContinuousCritic):
    """SB3's ContinuousCritic whose q1_forward is the lowest of its heads: (n, 1)."""

    def q1_forward(self, obs: PyTorchObs, actions: th.Tensor) -> th.Tensor:
        return th.cat(self(obs, actions), dim=1).min(dim=1, keepdim=True).values


class LayerNormTD3Policy(_LayerNormMixin, td3_policies.MultiInputPolicy):
    """DDPG's and TD3's MultiInputPolicy with LayerNorm and the actor's value (module docstring)."""

    actor_value: str

    def __init__(self, *args: Any, actor_value: str = "first", **kwargs: Any):
        object.__setattr__(self, "actor_value", actor_value)  # before BasePolicy.__init__ builds the critics
        super().__init__(*args, **kwargs)

    def make_critic(self, features_extractor: Any = None) -> Any:
        heads = self.critic_kwargs["n_critics"]
        self.critic_kwargs["n_critics"] = min(heads, TWIN)
        try:  # the twin heads from the run's own draws, so every other network gets the same draws too
            critic = super().make_critic(features_extractor)
            if heads > TWIN:  # the further heads from their own generator, seeded from the run's seed
                self.critic_kwargs["n_critics"] = heads - TWIN
                with own_draws(FURTHER_HEADS_SEED):
                    further = super().make_critic(features_extractor)
                for q_net in further.q_networks:
                    critic.add_module(f"qf{len(critic.q_networks)}", q_net)
                    critic.q_networks.append(q_net)
                critic.n_critics = heads
        finally:
            self.critic_kwargs["n_critics"] = heads
        if self.actor_value == "lowest":  # the same module; only q1_forward differs
            critic.__class__ = LowestHeadCritic
        return critic

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return super()._get_constructor_parameters() | {"actor_value": self.actor_value}


class LayerNormSACPolicy(_LayerNormMixin, sac_policies.MultiInputPolicy):
    """SAC's MultiInputPolicy with LayerNorm (module docstring)."""


class LayerNormTQCPolicy(_LayerNormMixin, tqc_policies.MultiInputPolicy):
    """TQC's MultiInputPolicy with LayerNorm (module docstring)."""


#: The LayerNorm policy of each algorithm (AgentConfig.algo).
LAYER_NORM_POLICIES: dict[str, type[BasePolicy]] = {
    "ddpg": LayerNormTD3Policy,
    "td3": LayerNormTD3Policy,
    "sac": LayerNormSACPolicy,
    "tqc": LayerNormTQCPolicy,
}


def policy_for(algo: str, layer_norm: str, own_critics: bool = False) -> str | type[BasePolicy]:
    """The policy argument of the algorithm: "MultiInputPolicy" (its own) without LayerNorm, and for
    TD3 without the critics' options (`own_critics`: AgentConfig.critics or actor_value set)."""
    return "MultiInputPolicy" if layer_norm == "none" and not own_critics else LAYER_NORM_POLICIES[algo]
