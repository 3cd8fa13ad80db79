"""Training configuration: HerConfig, DemoConfig, AgentConfig and TrainConfig, frozen and validated on construction.

Each field's docstring is its `--help` text: tsrl.cli builds its options from these classes with tyro,
so a new field is a new option (`arg(...)` annotations name a few: --env, --her, --her-strategy; the
AgentConfig options carry no prefix). Defaults follow
the paper (DDPG + HER, MLPs [256, 256], lr 1e-3, updates after every two episodes); the other
defaults come from the HER paper's Fetch settings and rl-baselines3-zoo's FetchReach entries, with the
reason next to each (docs/training.md has the full table).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal

from tyro.conf import OmitArgPrefixes, arg

from ..envs.actions import ACTION_MODES
from ..envs.keys import OBS_KEYS
from ..envs.observations import OBS_PRESETS
from ..envs.tasks import check_reward_scale
from ..exceptions import InvalidConfig, check_int, check_positive, is_int, is_number

Algo = Literal["ddpg", "td3", "sac", "tqc", "bc"]
Learner = Literal["paper", "fast"]
LayerNorm = Literal["none", "critic", "both"]
ActorValue = Literal["first", "lowest"]
HerRelabel = Literal["feature", "plain"]
HerStrategy = Literal["future", "final", "episode"]
#: The algorithms (stable-baselines3's or sb3-contrib's class of the same name, upper case;
#: tsrl.agents.factory), and bc: behaviour cloning of the demonstrations (tsrl.agents.bc).
ALGOS: tuple[str, ...] = typing.get_args(Algo)
#: The algorithm that clones demonstrations (tsrl.agents.bc).
BC = "bc"
LEARNERS: tuple[str, ...] = typing.get_args(Learner)
LAYER_NORMS: tuple[str, ...] = typing.get_args(LayerNorm)
ACTOR_VALUES: tuple[str, ...] = typing.get_args(ActorValue)
#: The algorithms whose critic heads AgentConfig.critics sets (stable-baselines3's n_critics).
CRITIC_ENSEMBLE_ALGOS = ("td3",)
#: The frozen clone's episodes the fast learner's acting gate measures by default (AgentConfig.
#: clone_episodes): as many as its window of the choice (tsrl.agents.acting_gate.WINDOW).
CLONE_EPISODES = 20
#: Measured episodes each of the gate's kinds needs before the choice may act (tsrl.agents.acting_gate;
#: here so that the configuration's check reads it without importing the gate's torch code).
MIN_EPISODES = 10
#: Each learner preset's value of the options left at None (AgentConfig.learner). paper: today's
#: agent (the paper's settings). fast (issue 55, studies/learner-from-demos): a learner that starts at
#: its demonstrations: the actor pre-trained by behaviour cloning (bc_steps) before the first env
#: step, twin critics (TD3) with LayerNorm, UTD 2, half of each batch from the demonstrations, gamma
#: 0.98, no random steps, TD3+BC's anchored actor loss after a warm-up in which it only clones, the
#: clone kept frozen beside the actor with the critic choosing between them in acting and in the TD
#: target (IBRL; tsrl.agents.reference), and the observation normaliser fixed at the demonstrations'
#: statistics (as the clone was fitted), and a reward that counts success only within half the
#: task's tolerances (a margin; success is judged at the tolerances), and the episodes' discounted
#: returns as a lower bound of the critic where it fits (return_bound; tsrl.agents.return_bound).
#: demos_reset_prob applies only where demonstrations are on;
#: bc_pretrain, reference and fixed_normalizer are not options.
LEARNER_PRESETS: dict[str, dict[str, Any]] = {
    "paper": {
        "algo": "ddpg", "layer_norm": "none", "utd": None, "learning_starts": 500, "gamma": 0.95,
        "action_noise": 0.2, "demos_batch_share": 0.125, "demos_reset_prob": 0.0, "demos_bc_anchor": None,
        "demos_bc_anchor_warmup": 0, "bc_pretrain": False, "reference": False, "fixed_normalizer": False,
        "reward_scale": 1.0, "return_bound": 0.0,
    },
    "fast": {
        "algo": "td3", "layer_norm": "critic", "utd": 2.0, "learning_starts": 0, "gamma": 0.98,
        "action_noise": 0.1, "demos_batch_share": 0.5, "demos_reset_prob": None, "demos_bc_anchor": 0.25,
        "demos_bc_anchor_warmup": 2_500, "bc_pretrain": True, "reference": True, "fixed_normalizer": True,
        "reward_scale": 0.5, "return_bound": 1.0,
    },
}  # fmt: skip
HER_RELABEL: tuple[str, ...] = typing.get_args(HerRelabel)
HER_STRATEGIES: tuple[str, ...] = typing.get_args(HerStrategy)
#: Keys of a goal environment's observation dict that the networks may see (AgentConfig.policy_inputs).
POLICY_INPUTS: tuple[str, ...] = OBS_KEYS  # any key of the dict
#: `obs` / `action` value for environments that are not tsrl's (e.g. FetchReach-v4 in benchmarks).
NATIVE = "native"
#: `action` value that keeps the task's own action (its file's [action]) instead of a built-in mode.
TASK_ACTION = "task"
#: An `env_id` ending so is a task file (docs/tasks.md), built by tsrl/Task-v0.
TASK_FILE_SUFFIX = ".toml"


def task_defaults(env_id: str) -> tuple[str, str]:
    """(obs, action) of a tsrl environment where they are not given: the task's own, as gym.make(env_id)
    builds it (its file's `observation`, and its `action`: a built-in mode's name or TASK_ACTION for an
    `[action]` table), for a registered id and a task file alike."""
    from ..envs import load_task
    from ..envs.registration import ENV_IDS

    source = env_id.removeprefix("tsrl/") if env_id in ENV_IDS else Path(env_id).expanduser().resolve()
    task = load_task(source)  # a missing or bad file: one line naming it
    mode = task.action if isinstance(task.action, str) and task.action in ACTION_MODES else None
    return task.observation, mode or TASK_ACTION


def tsrl_env_ids() -> list[str]:
    """tsrl's registered environment ids (importing tsrl registers them)."""
    import gymnasium as gym

    import tsrl  # noqa: F401

    return sorted(env_id for env_id in gym.registry if env_id.startswith("tsrl/"))


def check_env_id(env_id: str) -> None:
    """Raises InvalidConfig listing tsrl's environments unless `env_id` is one of them (or a task file)."""
    if env_id not in tsrl_env_ids() and not env_id.endswith(TASK_FILE_SUFFIX):
        raise outside_tsrl(env_id)


def outside_tsrl(env_id: str) -> InvalidConfig:
    """The one answer to an environment that is not tsrl's, wherever it is given (`tsrl train` or
    TrainConfig): what is accepted, and that others train from Python only (obs and action native)."""
    return InvalidConfig(
        f"unknown environment {env_id!r}; accepted: {', '.join(tsrl_env_ids())}, or a task file "
        f"(*{TASK_FILE_SUFFIX}); environments outside tsrl (Gymnasium goal environments such as "
        f"FetchReach-v4) train from Python only: TrainConfig(obs={NATIVE!r}, action={NATIVE!r})"
    )


def _choice(name: str, value: Any, accepted: tuple[str, ...]) -> None:
    if value not in accepted:
        raise InvalidConfig(f"unknown {name} {value!r}; accepted: {', '.join(accepted)}")


@dataclass(frozen=True)
class HerConfig:
    """Hindsight Experience Replay: how stored transitions get new goals."""

    relabel: Annotated[HerRelabel, arg(name="her-relabel", aliases=("--her",))] = "feature"
    """feature: relabelled transitions get their goal-dependent observation features recomputed for the
    new goal (FeatureHerReplayBuffer, exact); plain: stable-baselines3's HER, which replaces only
    desired_goal (goal-dependent features then contradict the new goal)."""
    strategy: Annotated[HerStrategy, arg(name="her-strategy")] = "future"
    """Where new goals come from: goals achieved later in the same episode (future, the HER paper's
    best), at its end (final), or anywhere in it (episode)."""
    n_sampled_goal: Annotated[int, arg(name="her-n-sampled-goal")] = 4
    """Relabelled transitions per real one: 4 means 80% of a batch is relabelled (HER paper's k = 4)."""

    def __post_init__(self) -> None:
        _choice("her relabel mode", self.relabel, HER_RELABEL)
        _choice("her strategy", self.strategy, HER_STRATEGIES)
        check_int("her n_sampled_goal", self.n_sampled_goal, 1)


@dataclass(frozen=True)
class DemoConfig:
    """Learning from demonstrations (Nair et al. 2018): a demonstration buffer, a Q-filtered BC loss."""

    path: Annotated[str | None, arg(name="demos", aliases=("--demos-path",))] = None
    """Demonstration file (.npz, written by `tsrl demos record`), Minari dataset folder (`--format
    minari`, or one written by Minari's own tools on a tsrl environment) or LeRobot dataset folder
    (`--format lerobot`, `tsrl evaluate --record`); None: no demonstrations."""
    batch_share: Annotated[float | None, arg(name="demos-batch-share")] = None
    """Share of every minibatch drawn from the demonstrations, HER-relabelled like the replay, in
    [0, 1); 0: demonstrations off. Default: the learner's (paper: 0.125, Nair et al.'s 128 of 1024;
    fast: 0.5, RLPD's symmetric sampling)."""
    batch_share_end: Annotated[float | None, arg(name="demos-batch-share-end")] = None
    """The share reached after `batch_share_steps` env steps, linearly from `batch_share` (then held);
    None: the share stays `batch_share`."""
    batch_share_steps: Annotated[int, arg(name="demos-batch-share-steps")] = 0
    """Env steps over which the share goes from `batch_share` to `batch_share_end`."""
    reset_prob: Annotated[float | None, arg(name="demos-reset-prob")] = None
    """Probability that a training episode starts from a demonstration's state (a random episode and
    step of the file, restored exactly; Nair et al. 2018) instead of the task's reset. Default: the
    learner's where demonstrations are on (paper and fast: None, no resets); without them None."""
    reset_curriculum_steps: Annotated[int, arg(name="demos-reset-curriculum-steps")] = 0
    """0: the restored step is uniform over the demonstration; N > 0: a reverse curriculum, the
    restored step drawn from the last steps of the demonstration, a window that grows linearly from
    the last step to the whole episode over N env steps."""
    reset_curriculum_success: Annotated[float, arg(name="demos-reset-curriculum-success")] = 0.0
    """0: off; s in (0, 1]: a reverse curriculum paced by success (RFCL's advance on success, over all
    demonstrations at once) instead of by env steps: the window of restored steps starts at the
    demonstration's last step and widens by a tenth of the demonstration whenever the last 20 episodes
    started from a demonstration state since it last widened succeeded at a rate >= s."""
    reset_frontier_k: Annotated[int, arg(name="demos-reset-frontier-k")] = 0
    """0: off; k > 0: RFCL's reverse curriculum (Tao et al. 2024), one frontier per demonstration,
    first at its first successful state, moved a few steps back after k of k successes from it;
    starts drawn at the frontier and an episode time limit that grows with the distance to the
    demonstration's end (tsrl.agents.demo_resets.DemoResets). Needs reset_prob > 0."""
    bc_anchor: Annotated[float | None, arg(name="demos-bc-anchor")] = None
    """alpha > 0: the actor loss is alpha * (-Q) / mean|Q(s, pi(s))| of the batch plus bc_weight x BC on
    every demonstration row, unfiltered (TD3+BC's anchor, Fujimoto & Gu 2021: the BC weight means the
    same at any scale of Q); None: Nair et al.'s -Q + bc_weight x Q-filtered BC. Default: the learner's
    (paper: None; fast: 0.25, a tenth of TD3+BC's offline 2.5: with 2.5 the cloned pick-and-place actor
    fell from 1.00 to 0.68 once the Q term was on, with 0.25 it held 0.98-1.00; one-seed probes,
    studies/learner-from-demos)."""
    bc_anchor_warmup: Annotated[int | None, arg(name="demos-bc-anchor-warmup")] = None
    """With bc_anchor: env steps during which the actor's Q term is off (the actor keeps cloning while
    the critic learns the values of what it does), then as many over which it ramps linearly to full.
    Default: the learner's (paper: 0; fast: 2,500)."""
    bc_weight: Annotated[float, arg(name="demos-bc-weight")] = 1.0
    """Weight of the behaviour-cloning loss (squared action error, mean over the demonstration rows)
    next to the actor's -mean Q; 0: demonstrations off (no demonstration rows, no BC loss: the agent
    without demonstrations, bit for bit)."""
    q_filter: Annotated[bool, arg(name="demos-q-filter")] = True
    """Clone a demonstrated action only where the critic rates it above the actor's:
    Q(s, a_demo) > Q(s, pi(s)) (Nair et al.'s Q-filter)."""

    def __post_init__(self) -> None:
        if self.path is not None and (not isinstance(self.path, str) or not self.path):
            raise InvalidConfig(f"demos path must be a file path or None; got {self.path!r}")
        for name in ("batch_share", "batch_share_end"):
            share = getattr(self, name)
            if share is None:
                continue
            if not is_number(share):
                raise InvalidConfig(f"demos {name} must be a number; got {share!r}")
            if not 0 <= share < 1:
                raise InvalidConfig(f"demos {name} must be in [0, 1); got {share}")
        check_positive("demos bc_weight", self.bc_weight, strict=False)
        if self.bc_anchor is not None and (
            not is_number(self.bc_anchor) or not 0 < self.bc_anchor < math.inf
        ):
            raise InvalidConfig(f"demos bc_anchor must be a number > 0 or None; got {self.bc_anchor!r}")
        if self.bc_anchor_warmup is not None:
            check_int("demos bc_anchor_warmup", self.bc_anchor_warmup, 0)
        check_int("demos batch_share_steps", self.batch_share_steps, 0)
        if (self.batch_share_end is None) != (self.batch_share_steps == 0):
            raise InvalidConfig(
                f"demos batch_share_end {self.batch_share_end} with batch_share_steps "
                f"{self.batch_share_steps}: give both (a share and the env steps > 0 to reach it) or neither"
            )
        if self.reset_prob is not None and (not is_number(self.reset_prob) or not 0 <= self.reset_prob <= 1):
            raise InvalidConfig(f"demos reset_prob must be in [0, 1]; got {self.reset_prob!r}")
        check_int("demos reset_curriculum_steps", self.reset_curriculum_steps, 0)
        success = self.reset_curriculum_success
        if not is_number(success) or not 0 <= success <= 1:
            raise InvalidConfig(f"demos reset_curriculum_success must be in [0, 1]; got {success!r}")
        check_int("demos reset_frontier_k", self.reset_frontier_k, 0)
        if self.reset_frontier_k and (success or self.reset_curriculum_steps):
            raise InvalidConfig(
                f"demos reset_frontier_k {self.reset_frontier_k} with reset_curriculum_steps "
                f"{self.reset_curriculum_steps} / reset_curriculum_success {success}: one reverse curriculum; "
                "accepted: the other two 0"
            )
        if success and self.reset_curriculum_steps:
            raise InvalidConfig(
                f"demos reset_curriculum_steps {self.reset_curriculum_steps} with reset_curriculum_success "
                f"{success}: one reverse curriculum, paced by env steps or by success; accepted: one of them 0"
            )

    @property
    def active(self) -> bool:
        """Whether demonstrations take part in training: a file, a batch share > 0 and a BC weight > 0.

        Either at 0 turns them off: the file is not read, the run is the one without demonstrations
        (its name, its agent, its run folder). Every "are demonstrations on?" asks this."""
        share = self.batch_share
        return self.path is not None and (share is None or share > 0) and self.bc_weight > 0

    @property
    def resets_suffix(self) -> str:
        """The run name's part for resets to demonstration states (TrainConfig.run_name): "" without
        them, else `__demo-resets-<prob>` and the reverse curriculum's `__frontier-<k>`,
        `__curriculum-steps-<N>` or `__curriculum-success-<s>`."""
        if not (self.active and self.reset_prob):
            return ""
        suffix = f"__demo-resets-{self.reset_prob:g}"
        suffix += f"__frontier-{self.reset_frontier_k}" if self.reset_frontier_k else ""
        suffix += f"__curriculum-steps-{self.reset_curriculum_steps}" if self.reset_curriculum_steps else ""
        suffix += (
            f"__curriculum-success-{self.reset_curriculum_success:g}" if self.reset_curriculum_success else ""
        )
        return suffix


@dataclass(frozen=True)
class AgentConfig:
    """Off-policy algorithm + HER; defaults are the paper's settings where it gives them."""

    # The defaults None of algo, learning_starts, gamma and action_noise stand for "the learner's":
    # __post_init__ replaces them (LEARNER_PRESETS), so a built config always holds the annotated type.
    algo: Algo = None  # type: ignore[assignment]
    """Off-policy algorithm, always combined with HER (default: the learner's; paper: DDPG, fast: TD3;
    tqc: sb3-contrib's TQC, a distributional critic); bc: behaviour cloning of --demos (no env step; its budget is bc_steps
    gradient steps, and eval_freq and checkpoint_freq count gradient steps)."""
    learner: Learner = "paper"
    """Preset of the learner options left unset (layer_norm, utd, demos batch share and reset
    probability): paper (today's agent, the paper's settings) or fast (LayerNorm critic, UTD 2,
    symmetric demonstration sampling and demonstration resets; docs/training.md). Options given
    explicitly win. Resolved on construction: dataclasses.replace(config, learner=...) of a built
    config keeps its values; build AgentConfig(learner=...) (the CLI and experiment files do)."""
    layer_norm: LayerNorm | None = None
    """LayerNorm after every hidden layer, before its ReLU (RLPD, Ball et al. 2023): none, critic,
    or both (critic and actor). Default: the learner's (paper: none)."""
    utd: float | None = None
    """Update-to-data ratio: gradient steps per env step (e.g. 2: 200 per update of two 50-step
    episodes), replacing gradient_steps. Default: the learner's (paper: none, gradient_steps per
    update)."""
    net_arch: tuple[int, ...] = (256, 256)
    """Hidden layers of actor and critic MLPs (paper: [256, 256])."""
    policy_inputs: tuple[str, ...] = POLICY_INPUTS
    """Keys of the observation dict that actor and critic see: any of observation, achieved_goal,
    desired_goal (default: all three). HER relabelling and normalisation still use every key."""
    learning_rate: float = 1e-3
    """Adam learning rate of actor and critic (paper: 0.001 for both)."""
    train_freq_episodes: int = 2
    """Networks are updated after every this many episodes (paper: two)."""
    gradient_steps: int = 40
    """Gradient steps per update, i.e. per `train_freq_episodes` episodes. 40 per two 50-step
    episodes is the HER paper's Fetch setting (n_batches = 40 per cycle of 2 episodes)."""
    batch_size: int = 256
    """Minibatch size (HER paper and rl-baselines3-zoo FetchReach: 256)."""
    buffer_size: int = 1_000_000
    """Replay buffer capacity in transitions (HER paper: 10^6). The buffer is allocated for
    min(buffer_size, total_timesteps + one update period): a run never needs more."""
    learning_starts: int = None  # type: ignore[assignment]
    """Env steps of uniformly random actions before the first update. Default: the learner's (paper:
    500, 10 episodes that fill the buffer with varied goals for HER, rl-baselines3-zoo's FetchReach
    uses 1000; fast: 0, it acts with its cloned actor from the first step)."""
    gamma: float = None  # type: ignore[assignment]
    """Discount factor. Default: the learner's (paper: 0.95, rl-baselines3-zoo FetchReach; fast: 0.98,
    the HER paper's 1 - 1/T, for episodes whose demonstrations succeed after 40-64 steps)."""
    tau: float = 0.05
    """Polyak coefficient of the target networks (HER paper: 1 - 0.95 = 0.05; SB3's default 0.005 is
    tuned for dense-reward locomotion and learns reach far slower)."""
    action_noise: float = None  # type: ignore[assignment]
    """Standard deviation of the Gaussian exploration noise on the [-1, 1] action, DDPG and TD3 only.
    Default: the learner's (paper: 0.2, HER paper and rl-baselines3-zoo; fast: 0.1, TD3's, around a
    cloned actor). SAC explores through its entropy term instead."""
    reward_scale: float = None  # type: ignore[assignment]
    """tsrl environments: the reward counts a step as a success only with every goal part within this
    fraction of the task's tolerances, in (0, 1] (SuccessSpec.reward_scale); success, and so evaluation,
    stays at the tolerances. With a sparse reward at the tolerance itself nothing teaches a margin:
    the push's misses end just outside it (studies/learner-from-demos). Default: the learner's (paper:
    1, the task's reward; fast: 0.5)."""
    action_l2: float = 0.0
    """Weight of a penalty on the actor's squared actions (mean over the batch and the [-1, 1] action's
    dimensions) added to the actor loss: OpenAI baselines' HER `action_l2` (1.0 on Fetch;
    tsrl.agents.action_penalty). 0 (the paper's): none."""
    normalize: bool = True
    """Normalise observation, achieved and desired goal with running mean and std (VecNormalize;
    measured on FetchReach-v4: 90% success after 2,000 env steps with it, 28,000 without). The replay
    buffer keeps raw values; normalisation is applied after HER relabelling."""
    clip_obs: float = 5.0
    """Normalised inputs are clipped to +-clip_obs (HER paper: 5)."""
    bc_steps: int = 8000
    """algo bc: gradient steps of behaviour cloning (its budget); the other algorithms: gradient steps
    of cloning that pre-train the actor before the first env step where the learner does (fast)."""
    bc_dropout: float = 0.1
    """Dropout after each hidden layer of a behaviour-cloning actor (algo bc, and the fast learner's
    reference clone), off when it acts."""
    residual: float = 0.0
    """alpha in (0, 1]: the fast learner's actor is a bounded residual on its frozen clone, its action
    clamp(clone(s) + alpha * r(s), -1, 1) with r its own network started at zero (residual policy
    learning; tsrl.agents.reference), so it moves each action component at most alpha from the clone's;
    0 (default): the actor is a policy of its own, started as a copy of the clone."""
    return_bound: float = None  # type: ignore[assignment]
    """Weight of a loss that pulls each critic value up to the discounted return its episode achieved
    from there under the row's goal, where it is below it (a lower bound of the optimal value:
    Monte Carlo augmented actor-critic, Wilcox et al. 2022; tsrl.agents.return_bound); ddpg, td3 or
    sac with feature-aware HER and gamma < 1; 0: none. Default: the learner's where it fits (paper:
    0; fast: 1), else 0."""
    adaptive_noise: bool = False
    """The fast learner's explore episodes measured and their noise's scale adapted to keep them
    winnable: halved while their success is below 3/4 of the noise-free choice's, doubled back (up
    to action_noise) at 95 % of it (tsrl.agents.acting_gate). False (default): action_noise
    throughout."""
    clone_episodes: int = CLONE_EPISODES
    """Episodes of the fast learner's frozen clone that its acting gate measures before the clone's
    place in the episode cycle explores; the gate compares the choice's last 20 episodes with the
    clone's success over all of these (tsrl.agents.acting_gate). More measure the clone better (it
    does not change); each costs an episode without exploration noise. 20 (default): as many as the
    choice's window."""
    distill_choice: float = 0.0
    """Weight of a loss that clones the fast learner's frozen clone into its actor on every row of the
    batch where the critic prefers the clone's action, as its choice does (tsrl.agents.choice_distillation):
    the actor learns what the choice does; needs the fast learner's reference. 0 (default): none."""
    clone_proposals: int = 0
    """K > 0: the fast learner's choice ranks, besides the actor's and its clone's actions, those of K
    thinned clones (the clone with K fixed dropout masks: a best of K + 2 by the critic, in acting and
    in the TD target; EMaQ, Ghasemipour et al. 2021; tsrl.agents.reference); needs the fast learner's
    reference and bc_dropout > 0. 0 (default): the actor's and the clone's only."""
    clones: int = 1
    """C > 1: the fast learner's reference is the mean action of C clones of the demonstrations, each
    trained as BC trains its actor (the first as without it, the others from their own draws; the
    actor starts as the first); cuts BC's seed-to-seed spread (tsrl.agents.reference.CloneEnsemble).
    Needs the fast learner's reference; not with residual or clone_proposals. 1 (default): one clone."""
    critics: int = 2
    """Critic networks (heads) of td3: its target and the fast learner's choice take the smallest of
    them (TD3's clipped double Q over N; IBRL's critic ensemble, Hu et al. 2023); the heads beyond two
    are drawn from their own generator, so the other networks start as without them. 2 (default):
    TD3's twin critics."""
    n_step: int = 1
    """N > 1: the critic's target is an N-step return: the rewards of each row's next N steps under its
    (relabelled) goal, then gamma^N times the target critic's value N steps on (fewer where the episode
    ends first; tsrl.agents.her). Faster credit for sparse rewards (DDPGfD, Vecerik et al. 2017; FastTD3,
    Seo et al. 2025); the steps' actions are the stored ones. ddpg, td3, sac or tqc under feature HER with
    gamma < 1. 1 (default): one-step targets."""
    actor_value: ActorValue = "first"
    """The critic value TD3's actor climbs: its first head (first, default: TD3's) or the lowest of its
    heads (lowest: IBRL's, so the actor does not climb one head's over-estimates; with demonstrations
    the Q scale of the BC-regularised actor loss is that value's too)."""
    her: HerConfig = field(default_factory=HerConfig)
    """Hindsight Experience Replay settings."""
    demos: DemoConfig = field(default_factory=DemoConfig)
    """Demonstrations (off by default)."""

    def __post_init__(self) -> None:
        _choice("learner", self.learner, LEARNERS)
        self._resolve_learner()
        _choice("algo", self.algo, ALGOS)
        _choice("layer_norm", self.layer_norm, LAYER_NORMS)
        check_reward_scale("reward_scale", self.reward_scale)
        if self.utd is not None and (not is_number(self.utd) or not self.utd > 0):
            raise InvalidConfig(
                f"utd {self.utd!r}: the update-to-data ratio is gradient steps per env step, > 0 "
                "(e.g. 0.5, 1, 2); accepted: a number > 0, or None for gradient_steps per update"
            )
        if not self.net_arch or any(not is_int(n) or n < 1 for n in self.net_arch):
            raise InvalidConfig(
                f"net_arch must be positive layer widths, e.g. 256 256; got {self.net_arch!r}"
            )
        for key in self.policy_inputs:
            _choice("policy input", key, POLICY_INPUTS)
        if not self.policy_inputs or len(set(self.policy_inputs)) < len(self.policy_inputs):
            raise InvalidConfig(
                f"policy_inputs must name each of {', '.join(POLICY_INPUTS)} at most once, at least one; "
                f"got {self.policy_inputs!r}"
            )
        for name in ("learning_rate", "train_freq_episodes", "batch_size", "buffer_size", "clip_obs"):
            check_positive(name, getattr(self, name))
        for name in ("gradient_steps", "learning_starts", "action_noise", "action_l2"):
            check_positive(name, getattr(self, name), strict=False)
        if not math.isfinite(self.action_l2):
            raise InvalidConfig(
                f"action_l2 must be a finite number >= 0 (0: no penalty); got {self.action_l2}"
            )
        if not 0 < self.gamma <= 1:
            raise InvalidConfig(f"gamma must be in (0, 1]; got {self.gamma}")
        if not 0 < self.tau <= 1:
            raise InvalidConfig(f"tau must be in (0, 1]; got {self.tau}")
        check_int("bc_steps", self.bc_steps, 0)
        if not is_number(self.bc_dropout) or not 0 <= self.bc_dropout < 1:
            raise InvalidConfig(f"bc_dropout must be in [0, 1); got {self.bc_dropout!r}")
        if not is_number(self.residual) or not 0 <= self.residual <= 1:
            raise InvalidConfig(
                f"residual {self.residual!r}: accepted: a number in [0, 1] (0: no residual actor)"
            )
        self._needs_reference("residual", "corrects the fast learner's clone")
        self._check_weight("return_bound", "no bound")
        self._check_return_bound()
        if not isinstance(self.adaptive_noise, bool):
            raise InvalidConfig(f"adaptive_noise {self.adaptive_noise!r}: accepted: true or false")
        if self.adaptive_noise and not (self.has_reference and self.action_noise > 0):
            raise InvalidConfig(
                f"adaptive_noise adapts the fast learner's explore noise: it needs --learner fast, algo td3 or "
                f"ddpg, demonstrations and action_noise > 0 (got learner {self.learner!r}, algo {self.algo!r}, "
                f"demos {self.demos.path!r}, action_noise {self.action_noise!r}); accepted without them: false"
            )
        self._check_clone_episodes()
        self._check_weight("distill_choice", "none")
        self._needs_reference("distill_choice", "clones the fast learner's clone into its actor")
        check_int("clone_proposals", self.clone_proposals, 0)
        self._needs_reference("clone_proposals", "thins the fast learner's clone")
        if self.clone_proposals and not self.bc_dropout > 0:
            raise InvalidConfig(
                f"clone_proposals {self.clone_proposals!r} thins the clone by its dropout, but bc_dropout is "
                f"{self.bc_dropout!r}; accepted: bc_dropout in (0, 1) or clone_proposals 0"
            )
        self._check_critics()
        self._check_clones()
        self._check_n_step()
        if self.algo == BC:
            self._check_bc()

    def _check_clones(self) -> None:
        """clones: an int >= 1; more than one only for the fast learner's reference, without the
        options that read a single clone's network."""
        check_int("clones", self.clones, 1)
        if self.clones == 1:
            return
        if not self.has_reference:
            raise InvalidConfig(
                f"clones {self.clones!r} averages the fast learner's clones: it needs --learner fast, algo td3 or "
                f"ddpg and demonstrations (got learner {self.learner!r}, algo {self.algo!r}, demos "
                f"{self.demos.path!r}); accepted without them: 1"
            )
        for name in ("residual", "clone_proposals"):
            if getattr(self, name):
                raise InvalidConfig(
                    f"clones {self.clones!r} with {name} {getattr(self, name)!r}: {name} reads one clone's network; "
                    f"accepted: clones 1, or {name} 0"
                )

    def _check_critics(self) -> None:
        """critics: an int >= 1, other than 2 only where the algorithm takes it; actor_value: lowest
        for td3 only."""
        check_int("critics", self.critics, 1)
        if self.critics != 2 and self.algo not in CRITIC_ENSEMBLE_ALGOS:
            raise InvalidConfig(
                f"critics {self.critics!r} sets the critic heads of {', '.join(CRITIC_ENSEMBLE_ALGOS)}, but algo "
                f"is {self.algo!r}; accepted with it: critics 2 (the default)"
            )
        _choice("actor_value", self.actor_value, ACTOR_VALUES)
        if self.actor_value != "first" and self.algo != "td3":
            raise InvalidConfig(
                f"actor_value {self.actor_value!r} sets the value TD3's actor climbs, but algo is {self.algo!r}; "
                "accepted with it: first (the default)"
            )

    def _check_weight(self, name: str, zero: str) -> None:
        """The loss weight `name`: a finite number >= 0, where 0 means `zero`."""
        value = getattr(self, name)
        if not is_number(value) or not 0 <= value < math.inf:
            raise InvalidConfig(f"{name} {value!r}: accepted: a finite number >= 0 (0: {zero})")

    def _needs_reference(self, name: str, what: str) -> None:
        """The option `name`, where set, `what` (a phrase): only the fast learner's clone has it."""
        value = getattr(self, name)
        if value and not self.has_reference:
            raise InvalidConfig(
                f"{name} {value!r} {what}: it needs --learner fast, algo td3 or ddpg and demonstrations (got "
                f"learner {self.learner!r}, algo {self.algo!r}, demos {self.demos.path!r}); accepted without "
                "them: 0"
            )

    def _check_clone_episodes(self) -> None:
        check_int("clone_episodes", self.clone_episodes, MIN_EPISODES)
        if self.clone_episodes != CLONE_EPISODES and not self.has_reference:
            raise InvalidConfig(
                f"clone_episodes {self.clone_episodes!r} sets how long the fast learner's gate measures its "
                f"clone: it needs --learner fast, algo td3 or ddpg and demonstrations (got learner "
                f"{self.learner!r}, algo {self.algo!r}, demos {self.demos.path!r}); accepted without them: "
                f"{CLONE_EPISODES}"
            )

    def _check_n_step(self) -> None:
        check_int("n_step", self.n_step, 1)
        fits = self.algo in ("ddpg", "td3", "sac", "tqc") and self.her.relabel == "feature"
        if self.n_step > 1 and not (fits and is_number(self.gamma) and self.gamma < 1):
            raise InvalidConfig(
                f"n_step {self.n_step!r} makes the critic's target an N-step return of ddpg, td3, sac or tqc "
                f"under feature HER with gamma < 1 (got algo {self.algo!r}, her relabel {self.her.relabel!r}, "
                f"gamma {self.gamma!r}); accepted with these: 1"
            )

    def _check_return_bound(self) -> None:
        if self.return_bound > 0 and not self._bound_applies:
            raise InvalidConfig(
                f"return_bound {self.return_bound!r} bounds a ddpg, td3 or sac critic under feature HER with "
                f"gamma < 1 (got algo {self.algo!r}, her relabel {self.her.relabel!r}, gamma {self.gamma!r}); "
                "accepted with these: 0"
            )

    @property
    def starts_from_clone(self) -> bool:
        """The actor is pre-trained by behaviour cloning before the first env step (the learner's
        bc_pretrain, with demonstrations and bc_steps > 0)."""
        return bool(LEARNER_PRESETS[self.learner]["bc_pretrain"]) and self.demos.active and self.bc_steps > 0

    @property
    def _bound_applies(self) -> bool:
        """A return bound fits the critic: ddpg, td3 or sac under feature HER with gamma < 1."""
        fits = self.algo in ("ddpg", "td3", "sac") and self.her.relabel == "feature"
        return fits and is_number(self.gamma) and self.gamma < 1

    @property
    def has_reference(self) -> bool:
        """The clone stays frozen beside a DDPG/TD3 actor, the critic choosing (tsrl.agents.reference)."""
        return (
            self.starts_from_clone
            and bool(LEARNER_PRESETS[self.learner]["reference"])
            and self.algo in ("ddpg", "td3")
        )

    @property
    def fixed_normalizer(self) -> bool:
        """The observation normaliser keeps the demonstrations' statistics and no env step moves them:
        behaviour cloning, and a learner whose actor starts as a clone fitted under them."""
        if self.algo == BC:
            return True
        return self.starts_from_clone and bool(LEARNER_PRESETS[self.learner]["fixed_normalizer"])

    def _check_bc(self) -> None:
        """Behaviour cloning needs demonstrations and takes none of the options of learning from
        env steps: each such option given is refused in one line."""
        if not self.demos.active:
            raise InvalidConfig(
                f"algo {BC} clones demonstrations: give --demos FILE (with demos batch_share and bc_weight "
                f"> 0); got demos {self.demos.path!r}"
            )
        if self.bc_steps < 1:
            raise InvalidConfig(
                f"algo {BC}: bc_steps is its budget in gradient steps, >= 1; got {self.bc_steps}"
            )
        default = AgentConfig(demos=DemoConfig(path=self.demos.path))
        rl_only = {
            "learner": "paper",
            "her": default.her,
            "action_noise": default.action_noise,
            "utd": None,
            "action_l2": default.action_l2,
            "demos.reset_prob": None,
            "demos.batch_share_end": None,
        }
        for name, accepted in rl_only.items():
            owner, _, key = name.rpartition(".")
            value = getattr(self.demos if owner else self, key)
            if value != accepted:
                raise InvalidConfig(
                    f"algo {BC} learns from the demonstrations alone, without env steps: {name} {value!r} "
                    f"does not apply; accepted: {accepted!r} (the default)"
                )

    def _resolve_learner(self) -> None:
        """Options left at None get the learner preset's value (LEARNER_PRESETS); resets to
        demonstration states without demonstrations are refused here, before the reset probability is."""
        preset = LEARNER_PRESETS[self.learner]
        for name in ("algo", "layer_norm", "utd", "learning_starts", "gamma", "action_noise", "reward_scale"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, preset[name])
        if self.return_bound is None:
            object.__setattr__(self, "return_bound", preset["return_bound"] if self._bound_applies else 0.0)
        demos = self.demos
        if demos.batch_share is None:
            demos = dataclasses.replace(demos, batch_share=preset["demos_batch_share"])
        if demos.bc_anchor is None and preset["demos_bc_anchor"] is not None:
            demos = dataclasses.replace(demos, bc_anchor=preset["demos_bc_anchor"])
        if demos.bc_anchor_warmup is None:
            demos = dataclasses.replace(demos, bc_anchor_warmup=preset["demos_bc_anchor_warmup"])
        if not demos.active and (
            demos.reset_prob
            or demos.reset_curriculum_steps
            or demos.reset_curriculum_success
            or demos.reset_frontier_k
        ):
            raise InvalidConfig(
                f"demos reset_prob {demos.reset_prob} / reset_curriculum_steps {demos.reset_curriculum_steps} "
                f"/ reset_curriculum_success {demos.reset_curriculum_success} without demonstrations: "
                "resets to demonstration states need a demonstration file (--demos) with batch_share and "
                "bc_weight > 0; accepted without: reset_prob 0, reset_curriculum_steps 0, "
                "reset_curriculum_success 0"
            )
        if demos.reset_prob is None and demos.active and preset["demos_reset_prob"]:
            # None stays None (no resets) otherwise: a file given later (dataclasses.replace, as
            # experiments add theirs, or with --resume) finds the same config as the paper's runs have
            demos = dataclasses.replace(demos, reset_prob=preset["demos_reset_prob"])
        for name in ("reset_curriculum_steps", "reset_curriculum_success", "reset_frontier_k"):
            if getattr(demos, name) > 0 and not demos.reset_prob:
                raise InvalidConfig(
                    f"demos {name} {getattr(demos, name)} with reset_prob {demos.reset_prob}: a reset "
                    f"curriculum needs demonstration resets; accepted: reset_prob > 0, or {name} 0"
                )
        object.__setattr__(self, "demos", demos)


@dataclass(frozen=True)
class TrainConfig:
    """One training run: environment x observation x action x algorithm x seed, and its budget."""

    env_id: Annotated[str, arg(aliases=("--env", "--task"))] = "tsrl/UR5eReach-v0"
    """Registered environment id, or the path of a task file (TOML, docs/tasks.md) to train on."""
    # Help texts built from the registries, so that they list every preset and mode there is.
    # Left empty (not given), obs and action are the task file's own, else the defaults (__post_init__).
    obs: Annotated[
        str,
        arg(
            help=f"Observation preset ({', '.join(OBS_PRESETS)}) or a task-map spec string.",
            help_behavior_hint="(default: the task's own, as gym.make builds it)",
        ),
    ] = ""
    action: Annotated[
        str,
        arg(
            help=f"Action mode: {', '.join(ACTION_MODES)}, or {TASK_ACTION} (the task file's own action).",
            help_behavior_hint="(default: the task's own, as gym.make builds it)",
        ),
    ] = ""
    seed: int = 0
    """Seed of networks, exploration, replay sampling and training episodes."""
    total_timesteps: int = 20_000
    """Training budget in env steps (the run ends at the first update boundary at or after it)."""
    eval_freq: int = 500
    """Evaluate every this many env steps (at the first update boundary after), and at step 0."""
    eval_episodes: int = 20
    """Deterministic evaluation episodes, each with its own seed (the same seeds at every evaluation)."""
    checkpoint_freq: int = 5000
    """Checkpoint (model, replay buffer, normaliser) every this many env steps, at the end, and on
    SIGINT/SIGTERM; a killed run resumes from the latest one."""
    torch_threads: int = 1
    """Torch CPU threads; 1 is fastest for [256, 256] MLPs with batches of 256."""
    agent: OmitArgPrefixes[AgentConfig] = field(default_factory=AgentConfig)
    """Algorithm and HER settings."""
    init_from: Annotated[str | None, arg(metavar="RUN_DIR")] = None
    """Start from this run's networks (actor, critic and their targets) and observation normaliser, its
    newest usable checkpoint: a run of the same algorithm, network sizes, policy inputs and layout
    (another arm's; tsrl.agents.init_from). The replay buffer starts empty; demonstrations may be added."""

    def __post_init__(self) -> None:
        if not isinstance(self.env_id, str) or not self.env_id:
            raise InvalidConfig(f"env_id must be a registered environment id; got {self.env_id!r}")
        if self.init_from is not None:
            if not isinstance(self.init_from, str) or not self.init_from:
                raise InvalidConfig(f"init_from must be a run folder; got {self.init_from!r}")
            object.__setattr__(self, "init_from", str(Path(self.init_from).expanduser().resolve()))
        if self.is_task_file:
            object.__setattr__(self, "env_id", str(Path(self.env_id).expanduser().resolve()))
        if self.is_tsrl_env:  # obs and action not given: the task's own (task_defaults)
            if "" in (self.obs, self.action):
                check_env_id(self.env_id)
                own = task_defaults(self.env_id)
                for name, value in zip(("obs", "action"), own, strict=True):
                    if getattr(self, name) == "":
                        object.__setattr__(self, name, value)
            if self.obs == NATIVE or self.action == NATIVE:
                raise InvalidConfig(f"obs/action {NATIVE!r} is only for environments outside tsrl")
            _choice("action", self.action, (*ACTION_MODES, TASK_ACTION))
            if not isinstance(self.obs, str) or not self.obs.strip():
                raise InvalidConfig(
                    f"obs must be a preset ({', '.join(OBS_PRESETS)}) or a task-map spec; got {self.obs!r}"
                )
        elif self.obs != NATIVE or self.action != NATIVE:
            raise outside_tsrl(self.env_id)
        check_int("seed", self.seed, 0)
        for name in ("total_timesteps", "eval_freq", "eval_episodes", "checkpoint_freq", "torch_threads"):
            value = getattr(self, name)
            if not is_int(value):
                raise InvalidConfig(f"{name} must be an integer; got {value!r}")
            check_positive(name, value)

    @property
    def is_task_file(self) -> bool:
        return self.env_id.endswith(TASK_FILE_SUFFIX)

    @property
    def is_tsrl_env(self) -> bool:
        return self.env_id.startswith("tsrl/") or self.is_task_file

    @property
    def gym_id(self) -> str:
        """The id gym.make gets: env_id, or tsrl/Task-v0 for a task file."""
        from ..envs import TASK_ENV_ID

        return TASK_ENV_ID if self.is_task_file else self.env_id

    @property
    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of gym.make: obs and action (unless the task's own) and the reward scale
        (unless 1) for tsrl environments, and for a task file the file (a run's copy: its Task, tsrl.agents.task_record) and its episode
        length; none for other environments."""
        if not self.is_tsrl_env:
            return {}
        kwargs: dict[str, Any] = {"obs": self.obs}
        if self.action != TASK_ACTION:
            kwargs["action"] = self.action
        if self.agent.reward_scale != 1.0:
            kwargs["reward_scale"] = self.agent.reward_scale
        if self.is_task_file:
            from ..envs import load_task
            from .task_record import recorded_task

            recorded = recorded_task(self.env_id)  # a run's copy of its task: as the run recorded it
            task = load_task(self.env_id) if recorded is None else recorded
            kwargs |= {
                "task": self.env_id if recorded is None else task,
                "max_episode_steps": task.episode_steps,
            }
        return kwargs

    @property
    def run_name(self) -> str:
        """`<env>__<obs>__<action>__<algo>__s<seed>`, e.g. tsrl-UR5eReach-v0__fs1__taskspace__ddpg__s0.

        A spec string in place of a preset becomes `spec-<hash>` (its text is in config.json); runs
        with stable-baselines3's plain HER get a `__her-plain` suffix, runs with demonstrations on
        (DemoConfig.active) `__demos`, runs started from another run's networks (init_from) `__init`,
        runs of another learner preset than paper `__<learner>` (e.g. `__fast`), runs that start episodes
        from demonstration states `__demo-resets-<prob>` (with a reverse curriculum `__frontier-<k>`,
        `__curriculum-steps-<N>` or `__curriculum-success-<s>`), runs with an action
        penalty `__action-l2-<weight>`, runs with a residual actor `__residual-<alpha>`, runs with a return bound
        `__return-bound-<weight>`, runs with adaptive noise `__adaptive-noise`, runs whose gate
        measures the clone on N episodes other than 20 `__clone-episodes-<N>`, runs that distil the
        choice into the actor `__distill-choice-<weight>`, runs whose choice ranks K thinned clones too
        `__clone-proposals-<K>`, runs whose reference averages C clones `__clones-<C>`, runs with N critics
        other than 2 `__critics-<N>`, runs with N-step targets `__n-step-<N>`, runs whose actor climbs
        the lowest head `__actor-lowest`.
        """
        suffix = "" if self.agent.her.relabel == "feature" else f"__her-{self.agent.her.relabel}"
        suffix += "__demos" if self.agent.demos.active else ""
        suffix += "__init" if self.init_from is not None else ""
        suffix += "" if self.agent.learner == "paper" else f"__{self.agent.learner}"
        suffix += self.agent.demos.resets_suffix
        suffix += f"__action-l2-{self.agent.action_l2:g}" if self.agent.action_l2 else ""
        suffix += f"__residual-{self.agent.residual:g}" if self.agent.residual else ""
        suffix += f"__return-bound-{self.agent.return_bound:g}" if self.agent.return_bound else ""
        suffix += "__adaptive-noise" if self.agent.adaptive_noise else ""
        suffix += (
            f"__clone-episodes-{self.agent.clone_episodes}"
            if self.agent.clone_episodes != CLONE_EPISODES
            else ""
        )
        suffix += f"__distill-choice-{self.agent.distill_choice:g}" if self.agent.distill_choice else ""
        suffix += f"__clone-proposals-{self.agent.clone_proposals}" if self.agent.clone_proposals else ""
        suffix += f"__clones-{self.agent.clones}" if self.agent.clones != 1 else ""
        suffix += f"__critics-{self.agent.critics}" if self.agent.critics != 2 else ""
        suffix += f"__n-step-{self.agent.n_step}" if self.agent.n_step != 1 else ""
        suffix += f"__actor-{self.agent.actor_value}" if self.agent.actor_value != "first" else ""
        return f"{self.env_name}__{self.agent.algo}__s{self.seed}{suffix}"

    @property
    def env_name(self) -> str:
        """`<env>__<obs>__<action>`, the environment part of `run_name` (file-name safe)."""
        obs = self.obs
        if obs not in OBS_PRESETS and obs != NATIVE:
            import hashlib

            obs = "spec-" + hashlib.sha1(obs.encode()).hexdigest()[:8]
        env = f"task-{Path(self.env_id).stem}" if self.is_task_file else self.env_id.replace("/", "-")
        return f"{env}__{obs}__{self.action}"

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)
