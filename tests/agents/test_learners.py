"""Learner options (issue 27): LayerNorm networks, update-to-data ratio, the demonstration share's
schedule, resets to demonstration states, TQC + feature HER, the learner presets and their bad input.
Each option changes only what it says; the defaults are today's agent."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from sb3_contrib import TQC
from stable_baselines3 import DDPG
from torch import nn
from training_helpers import fill_with_random_episodes, saved_reach_demos, tiny

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env
from tsrl.agents.config import LEARNER_PRESETS, DemoConfig
from tsrl.agents.demo_files import DemoFileError, save_demos
from tsrl.agents.demo_resets import DemoResets, replay_states
from tsrl.agents.demonstrators import record_demos
from tsrl.agents.demos import DemoReplayBuffer, first_q
from tsrl.agents.factory import make_env
from tsrl.agents.her import FeatureHerReplayBuffer
from tsrl.agents.learners import with_layer_norm
from tsrl.envs.keys import OBS_KEYS
from tsrl.exceptions import InvalidConfig

REACH, PICK = "tsrl/UR5eReach-v0", "tsrl/UR5ePickPlace-v0"


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 4)


@pytest.fixture(scope="module")
def pick_demos(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("demos") / "pick.npz"
    return save_demos(record_demos(PICK, 2, obs="fs1", seed=0), path)


def _parameters_after_updates(cfg: TrainConfig, steps: int = 200) -> dict[str, th.Tensor]:
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(steps)
    return {k: v.clone() for k, v in model.policy.state_dict().items()}


# -- the defaults are today's agent --------------------------------------------------------------
def test_paper_learner_resolves_to_todays_settings_and_the_same_parameters():
    a = AgentConfig()
    assert (a.learner, a.layer_norm, a.utd) == ("paper", "none", None)
    assert (a.demos.batch_share, a.demos.reset_prob, a.demos.batch_share_end) == (0.125, None, None)
    assert AgentConfig(demos=DemoConfig(path="d.npz")).demos.reset_prob is None  # no resets
    today = _parameters_after_updates(tiny())
    spelled_out = _parameters_after_updates(tiny(learner="paper", layer_norm="none", utd=None))
    assert today.keys() == spelled_out.keys()
    assert all(th.equal(today[k], spelled_out[k]) for k in today)
    assert tiny().run_name == tiny(learner="paper").run_name  # no suffix: the same run folder as today


def test_fast_preset_fills_unset_options_and_explicit_ones_win(reach_demos):
    fast = AgentConfig(learner="fast", demos=DemoConfig(path=str(reach_demos)))
    preset = LEARNER_PRESETS["fast"]
    assert (fast.layer_norm, fast.utd) == (preset["layer_norm"], preset["utd"])
    assert (fast.demos.batch_share, fast.demos.reset_prob) == (
        preset["demos_batch_share"],
        preset["demos_reset_prob"],
    )
    given = AgentConfig(learner="fast", utd=0.5, demos=DemoConfig(path=str(reach_demos), batch_share=0.25))
    assert (given.utd, given.demos.batch_share, given.layer_norm) == (0.5, 0.25, preset["layer_norm"])
    without = AgentConfig(learner="fast")
    assert not without.demos.reset_prob  # no demonstrations: no resets
    later = dataclasses.replace(without, demos=dataclasses.replace(without.demos, path=str(reach_demos)))
    assert later.demos.reset_prob == preset["demos_reset_prob"]  # a file given later (experiments)
    cfg = TrainConfig(agent=fast)
    assert cfg.run_name.endswith("__demos__fast__return-bound-1")
    again = AgentConfig(**{k: getattr(fast, k) for k in ("learner", "layer_norm", "utd")}, demos=fast.demos)
    assert again == fast  # resolved values stay as they are when read back (config.json)


# -- each option changes what it says ----------------------------------------------------------
def test_layer_norm_inserts_one_norm_per_hidden_layer_and_keeps_the_linear_layers():
    mlp = nn.Sequential(nn.Linear(5, 8), nn.ReLU(), nn.Linear(8, 8), nn.ReLU(), nn.Linear(8, 2), nn.Tanh())
    out = with_layer_norm(mlp, n_hidden=2)
    kinds = [type(m).__name__ for m in out]
    assert kinds == ["Linear", "LayerNorm", "ReLU", "Linear", "LayerNorm", "ReLU", "Linear", "Tanh"]
    assert out[0] is mlp[0] and out[6] is mlp[4]
    x = th.randn(3, 5)
    # An independent computation: layer norms of the unchanged Linear layers' outputs.
    h = nn.functional.layer_norm(mlp[2](th.relu(nn.functional.layer_norm(mlp[0](x), (8,)))), (8,))
    assert th.allclose(out(x), th.tanh(mlp[4](th.relu(h))), atol=1e-6)


@pytest.mark.parametrize("algo", ["ddpg", "sac", "tqc"])
def test_layer_norm_critic_changes_only_the_critic(algo):
    def build(layer_norm: str):
        cfg = tiny(algo=algo, layer_norm=layer_norm)
        return make_agent(cfg, make_vec_env(cfg))

    plain, critic_only, both = build("none"), build("critic"), build("both")
    norms = lambda module: sum(isinstance(m, nn.LayerNorm) for m in module.modules())
    n_critics = len(plain.critic.q_networks)
    assert norms(plain.policy) == 0
    assert (norms(critic_only.critic), norms(critic_only.critic_target), norms(critic_only.actor)) == (
        2 * n_critics,
        2 * n_critics,
        0,
    )
    assert norms(both.actor) == 2
    # Same random draws: every parameter of the plain agent is in the LayerNorm one, equal.
    for name, value in plain.actor.state_dict().items():
        assert th.equal(critic_only.actor.state_dict()[name], value)
    linear = [m for m in critic_only.critic.modules() if isinstance(m, nn.Linear)]
    plain_linear = [m for m in plain.critic.modules() if isinstance(m, nn.Linear)]
    assert all(th.equal(a.weight, b.weight) for a, b in zip(linear, plain_linear, strict=True))
    # The critic optimiser trains the LayerNorm weights too.
    optimised = {id(p) for group in critic_only.critic.optimizer.param_groups for p in group["params"]}
    assert all(id(p) in optimised for p in critic_only.critic.parameters())


def test_layer_norm_policy_saves_and_loads(tmp_path):
    cfg = tiny(layer_norm="both")
    model = make_agent(cfg, make_vec_env(cfg))
    model.save(tmp_path / "m.zip")
    loaded = DDPG.load(tmp_path / "m.zip", env=make_vec_env(cfg), device="cpu")
    assert type(loaded.policy) is type(model.policy)
    for key, value in model.policy.state_dict().items():
        assert th.equal(loaded.policy.state_dict()[key], value)


def test_utd_sets_gradient_steps_per_env_step():
    for utd, expected in ((2.0, 200), (0.5, 50), (0.004, 1)):  # two 50-step episodes per update
        cfg = tiny(utd=utd)
        assert make_agent(cfg, make_vec_env(cfg)).gradient_steps == expected
    cfg = tiny()
    assert make_agent(cfg, make_vec_env(cfg)).gradient_steps == 10  # tiny's gradient_steps


def test_demo_share_follows_its_schedule(reach_demos):
    cfg = tiny(
        demos=DemoConfig(path=str(reach_demos), batch_share=0.5, batch_share_end=0.0, batch_share_steps=200)
    )
    model = make_agent(cfg, make_vec_env(cfg))
    buffer = model.replay_buffer
    assert isinstance(buffer, DemoReplayBuffer)
    assert buffer.demo_rows(100) == 50
    fill_with_random_episodes(buffer, model.env, 2)  # 100 transitions: half way
    assert buffer.n_added == 100 and buffer.demo_rows(100) == 25
    fill_with_random_episodes(buffer, model.env, 4)
    assert buffer.demo_rows(100) == 0
    buffer.sample(64)
    assert buffer.last_demo_batch is None  # no stale demonstration rows for the BC loss
    constant = tiny(demos=DemoConfig(path=str(reach_demos), batch_share=0.25))
    const_buffer = make_agent(constant, make_vec_env(constant)).replay_buffer
    fill_with_random_episodes(const_buffer, model.env, 2)
    assert const_buffer.demo_rows(100) == 25


# -- resets to demonstration states ------------------------------------------------------------
def test_demonstration_reset_restores_the_recorded_state_exactly(pick_demos):
    from tsrl.agents.demo_files import load_demos

    cfg = TrainConfig(env_id=PICK, obs="fs1")
    demos = load_demos(pick_demos)
    replay = make_env(cfg)
    states = replay_states(replay, demos, str(pick_demos))
    wrapped = DemoResets(make_env(cfg), states, prob=1.0, curriculum_steps=0, seed=3)
    independent = make_env(cfg)  # reaches the demonstration's states by running it
    for n in range(4):
        obs, info = wrapped.reset(seed=100 + n)
        episode, step = wrapped.last_reset
        assert info["demo_reset"] == (episode, step)
        for key in OBS_KEYS:  # the recorded observation, bit for bit
            assert np.array_equal(obs[key], getattr(demos, key)[episode, step]), key
        independent.reset(seed=int(demos.seeds[episode]))
        for t in range(step):
            independent.step(demos.actions[episode, t])
        a, b = wrapped.unwrapped.data, independent.unwrapped.data
        for field in ("qpos", "qvel", "act", "mocap_pos", "mocap_quat", "ctrl", "qacc_warmstart"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert np.array_equal(wrapped.unwrapped.get_state(), independent.unwrapped.get_state())
        for t in range(step, min(step + 3, demos.episode_steps)):  # and it goes on as the demonstration did
            obs = wrapped.step(demos.actions[episode, t])[0]
            assert np.array_equal(obs["observation"], demos.observation[episode, t + 1])
    # The episode's last step says where it started; a task-started episode's does not.
    done, info = False, {}
    while not done:
        _, _, terminated, truncated, info = wrapped.step(wrapped.action_space.sample())
        done = terminated or truncated
    assert info["demo_reset"] == wrapped.last_reset
    task_started = DemoResets(replay, states, prob=1e-9, curriculum_steps=0, seed=3)
    task_started.reset(seed=0)
    assert task_started.last_reset is None  # the task's own start
    done = False
    while not done:
        _, _, terminated, truncated, info = task_started.step(task_started.action_space.sample())
        done = terminated or truncated
    assert "demo_reset" not in info
    for env in (replay, wrapped, independent):
        env.close()


def test_reset_curriculum_starts_near_the_goal_and_widens(pick_demos):
    states = np.zeros((2, 51, 1))
    wrapped = DemoResets(gym.make("tsrl/UR5eReach-v0"), states, prob=1.0, curriculum_steps=1000, seed=0)
    assert {wrapped.start_step() for _ in range(50)} == {49}
    wrapped.env_steps = 500
    early = {wrapped.start_step() for _ in range(400)}
    assert min(early) == 25 and max(early) == 49
    wrapped.env_steps = 5000
    assert min(wrapped.start_step() for _ in range(400)) == 0
    wrapped.close()


def test_a_resumed_run_continues_its_reset_curriculum(reach_demos, tmp_path, monkeypatch):
    from tsrl.agents.training import resume, train

    demos = DemoConfig(path=str(reach_demos), reset_prob=1.0, reset_curriculum_steps=1000)
    run_dir = train(tiny(total=100, demos=demos), tmp_path, progress_bar=False)
    seen: list[int] = []  # the curriculum's env steps at each draw of the resumed run
    draw = DemoResets.start_step

    def recording(self: DemoResets) -> int:
        seen.append(self.env_steps)
        return draw(self)

    monkeypatch.setattr(DemoResets, "start_step", recording)
    resume(run_dir, total_timesteps=200, progress_bar=False)
    assert seen and seen[0] == 100 and seen == sorted(seen) and seen[-1] <= 200


def test_success_paced_curriculum_widens_only_after_enough_successes():
    states = np.zeros((2, 51, 1))
    wrapped = DemoResets(gym.make("tsrl/UR5eReach-v0"), states, 1.0, 0, seed=0, curriculum_success=0.75)
    assert {wrapped.start_step() for _ in range(50)} == {49}
    for outcome in [False] * 10 + [True] * 14:  # the last 20: 14 of 20 = 0.70 < 0.75
        wrapped._pace(outcome)
    assert wrapped.window == 1 and len(wrapped.outcomes) == 20
    wrapped._pace(True)  # the last 20: 15 of 20 = 0.75
    assert wrapped.window == 1 + 5 and wrapped.outcomes == []
    assert {wrapped.start_step() for _ in range(400)} == set(range(44, 50))
    for _ in range(20 * 12):  # ten strides reach the whole episode, and no further
        wrapped._pace(True)
    assert wrapped.window == 50 and min(wrapped.start_step() for _ in range(400)) == 0
    wrapped.close()


def test_success_paced_curriculum_counts_the_outcome_of_each_demonstration_started_episode(pick_demos):
    from tsrl.agents.demo_files import load_demos

    cfg = TrainConfig(env_id=PICK, obs="fs1")
    demos = load_demos(pick_demos)
    replay = make_env(cfg)
    states = replay_states(replay, demos, str(pick_demos))
    wrapped = DemoResets(make_env(cfg), states, 1.0, 0, seed=1, curriculum_success=0.5)
    finals = []
    for n in range(2):
        wrapped.reset(seed=n)
        episode, step = wrapped.last_reset
        assert step == demos.episode_steps - 1  # the window's one step
        done, t = False, step
        while not done:  # the demonstration's last action, held to the episode's end
            _, _, terminated, truncated, info = wrapped.step(demos.actions[episode, min(t, step)])
            done, t = terminated or truncated, t + 1
        finals.append(bool(info["is_success"]))
    assert wrapped.outcomes == finals
    for env in (replay, wrapped):
        env.close()


def test_a_resumed_run_continues_its_success_paced_curriculum(reach_demos, tmp_path, monkeypatch):
    import pickle

    from tsrl.agents.training import resume, train

    demos = DemoConfig(path=str(reach_demos), reset_prob=1.0, reset_curriculum_success=0.5)
    run_dir = train(tiny(total=100, demos=demos), tmp_path, progress_bar=False)
    [saved] = sorted((run_dir / "checkpoints").glob("step_*/rng.pkl"))
    curriculum = pickle.loads(saved.read_bytes())["demo_resets"]
    assert curriculum["window"] == 1 and len(curriculum["outcomes"]) == 2  # two 50-step episodes
    seen: list[int] = []  # outcomes counted at each draw of the resumed run
    draw = DemoResets.start_step

    def recording(self: DemoResets) -> int:
        seen.append(len(self.outcomes))
        return draw(self)

    monkeypatch.setattr(DemoResets, "start_step", recording)
    resume(run_dir, total_timesteps=200, progress_bar=False)
    assert seen[0] == 2 and seen[-1] == 4


@pytest.fixture(scope="module")
def paced_checkpoint(reach_demos, tmp_path_factory) -> Path:
    """The one checkpoint of a 100-step run with a success-paced reset curriculum."""
    from tsrl.agents.training import train

    demos = DemoConfig(path=str(reach_demos), reset_prob=1.0, reset_curriculum_success=0.5)
    run_dir = train(tiny(total=100, demos=demos), tmp_path_factory.mktemp("paced"), progress_bar=False)
    [checkpoint] = sorted((run_dir / "checkpoints").glob("step_*"))
    return checkpoint


@pytest.mark.parametrize(
    "curriculum",
    [{"window": 0, "outcomes": []}, {"window": 1}, {"window": 1, "outcomes": [0.5]}, [1, []]],
    ids=["window-0", "no-outcomes", "outcome-not-bool", "not-a-dict"],
)
def test_a_damaged_curriculum_state_makes_its_checkpoint_damaged(curriculum, paced_checkpoint, tmp_path):
    import pickle
    import shutil

    from tsrl.agents.checkpoint import DEMO_RESETS, verify_checkpoint
    from tsrl.agents.run_folder import DamagedCheckpoint

    checkpoint = Path(shutil.copytree(paced_checkpoint, tmp_path / paced_checkpoint.name))
    verify_checkpoint(checkpoint, normalized=True, for_training=True)  # as saved: usable
    rng = pickle.loads((checkpoint / "rng.pkl").read_bytes())
    (checkpoint / "rng.pkl").write_bytes(pickle.dumps(rng | {DEMO_RESETS: curriculum}))
    with pytest.raises(DamagedCheckpoint, match="rng.pkl.*'demo_resets' is not a curriculum state"):
        verify_checkpoint(checkpoint, normalized=True, for_training=True)


def test_a_file_the_environment_does_not_reproduce_cannot_be_reset_to(pick_demos):
    from tsrl.agents.demo_files import load_demos

    demos = load_demos(pick_demos)
    edited = dataclasses.replace(demos, actions=demos.actions[:, ::-1].copy())
    env = make_env(TrainConfig(env_id=PICK, obs="fs1"))
    with pytest.raises(DemoFileError, match="does not reproduce its"):
        replay_states(env, edited, "edited.npz")
    env.close()


def test_training_with_demonstration_resets_starts_episodes_from_demonstrations(reach_demos):
    cfg = tiny(demos=DemoConfig(path=str(reach_demos), reset_prob=1.0))
    venv = make_vec_env(cfg)  # VecNormalize(DummyVecEnv([Monitor(DemoResets(env))]))
    wrapper = venv.venv.envs[0].env
    assert isinstance(wrapper, DemoResets)
    venv.reset()
    assert wrapper.last_reset is not None
    without = make_vec_env(tiny(demos=DemoConfig(path=str(reach_demos))))  # reset_prob 0: no wrapper
    assert not isinstance(without.venv.envs[0].env, DemoResets)


def test_the_run_name_says_where_episodes_start(reach_demos):
    def name(**resets) -> str:
        return tiny(demos=DemoConfig(path=str(reach_demos), **resets)).run_name

    assert name().endswith("__s0__demos")  # no resets: the name as before
    assert name(reset_prob=0.0) == name()
    assert name(reset_prob=0.5).endswith("__s0__demos__demo-resets-0.5")
    assert name(reset_prob=0.5, reset_frontier_k=3).endswith("__demo-resets-0.5__frontier-3")
    assert name(reset_prob=1.0, reset_curriculum_steps=1000).endswith(
        "__demo-resets-1__curriculum-steps-1000"
    )
    assert name(reset_prob=1.0, reset_curriculum_success=0.75).endswith(
        "__demo-resets-1__curriculum-success-0.75"
    )
    assert len({name(), name(reset_prob=0.5), name(reset_prob=0.5, reset_frontier_k=3)}) == 3


# -- TQC + feature HER -------------------------------------------------------------------------
def test_tqc_with_feature_her_relabels_exactly():
    cfg = tiny(algo="tqc")
    model = make_agent(cfg, make_vec_env(cfg))
    assert isinstance(model, TQC) and isinstance(model.replay_buffer, FeatureHerReplayBuffer)
    buffer = model.replay_buffer
    fill_with_random_episodes(buffer, model.env, 4)
    env = model.env.venv.envs[0].unwrapped
    rng = np.random.default_rng(0)
    rows = rng.integers(0, buffer.pos, 64)
    batch = buffer._get_virtual_samples(rows, np.zeros(64, dtype=int), env=None)
    changed = 0
    for i, row in enumerate(rows):
        goal = batch.observations["desired_goal"][i].numpy()
        pairs = (
            (batch.observations, buffer.observations),
            (batch.next_observations, buffer.next_observations),
        )
        for samples, stored in pairs:
            expected = env.relabel({k: v[row, 0] for k, v in stored.items()}, goal)
            for key in OBS_KEYS:
                got = samples[key][i].numpy()
                assert np.array_equal(got, expected[key].astype(got.dtype)), key
        stored_goal = buffer.observations["desired_goal"][row, 0]
        changed += not np.array_equal(goal, stored_goal.astype(goal.dtype))
    assert changed > 32
    model.learn(200)  # and it trains


def test_bc_loss_works_with_tqc(reach_demos):
    cfg = tiny(algo="tqc", demos=DemoConfig(path=str(reach_demos)))
    model = make_agent(cfg, make_vec_env(cfg))
    model.learn(200)
    demo = model.replay_buffer.last_demo_batch
    assert demo is not None
    q = first_q(model.critic, demo.observations, demo.actions)
    quantiles = model.critic(demo.observations, demo.actions)
    assert q.shape == (len(demo.actions), 1)
    assert th.allclose(q[:, 0], quantiles[:, 0, :].mean(dim=1))
    assert "train/bc_loss" in model.logger.name_to_value


# -- bad input ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "make, expected",
    [
        (lambda p: AgentConfig(utd=0), "utd 0: the update-to-data ratio"),
        (lambda p: AgentConfig(learner="quick"), "unknown learner 'quick'; accepted: paper, fast"),
        (
            lambda p: AgentConfig(layer_norm="batch"),
            "unknown layer_norm 'batch'; accepted: none, critic, both",
        ),
        (lambda p: DemoConfig(path=p, batch_share=1.0), r"batch_share must be in \[0, 1\); got 1.0"),
        (lambda p: DemoConfig(path=p, batch_share_end=0.1), "give both"),
        (lambda p: AgentConfig(demos=DemoConfig(reset_prob=0.5)), "without demonstrations"),
        (lambda p: AgentConfig(demos=DemoConfig(reset_curriculum_steps=100)), "without demonstrations"),
        (
            lambda p: AgentConfig(demos=DemoConfig(path=p, reset_prob=0.0, reset_curriculum_steps=100)),
            "a reset curriculum needs",
        ),
        (lambda p: AgentConfig(demos=DemoConfig(path=p, reset_curriculum_steps=100)), "with reset_prob None"),
        (lambda p: DemoConfig(path=p, reset_prob=1.5), r"reset_prob must be in \[0, 1\]"),
        (
            lambda p: DemoConfig(path=p, reset_curriculum_steps=100, reset_curriculum_success=0.5),
            "one reverse curriculum, paced by env steps or by success",
        ),
        (
            lambda p: AgentConfig(demos=DemoConfig(path=p, reset_curriculum_success=0.5)),
            "demos reset_curriculum_success 0.5 with reset_prob None",
        ),
        (lambda p: DemoConfig(path=p, reset_curriculum_success=2.0), r"must be in \[0, 1\]; got 2.0"),
    ],
)
def test_bad_combinations_are_one_line(make, expected, reach_demos):
    with pytest.raises(InvalidConfig, match=expected) as err:
        make(str(reach_demos))
    assert "\n" not in str(err.value)


def test_cli_learner_fast_takes_the_preset_and_given_options_win(reach_demos):
    from tsrl.cli import parse

    fast = parse(["train", "--learner", "fast", "--demos", str(reach_demos)]).config.agent
    assert fast == AgentConfig(learner="fast", demos=DemoConfig(path=str(reach_demos)))
    given = parse(
        ["train", "--learner", "fast", "--layer-norm", "none", "--demos", str(reach_demos)]
    ).config.agent
    assert (given.layer_norm, given.utd) == ("none", LEARNER_PRESETS["fast"]["utd"])
    assert given.demos.reset_prob == LEARNER_PRESETS["fast"]["demos_reset_prob"]
    assert parse(["train"]).config.agent == AgentConfig()  # paper: today's options


def test_an_experiment_file_takes_learner_fast_and_its_recorded_demonstrations(tmp_path):
    from tsrl.experiments.config import load_experiment

    source = Path(__file__).resolve().parents[2] / "experiments" / "pick-place-box-tcp.toml"
    text = source.read_text()
    assert "[agent]\n" not in text and "[agent.her]" in text and "[demos]" in text
    (tmp_path / "fast.toml").write_text(
        text.replace("[agent.her]", '[agent]\nlearner = "fast"\n\n[agent.her]', 1)
    )
    run = load_experiment(tmp_path / "fast.toml", check_envs=False).runs(tmp_path)[0]
    preset = LEARNER_PRESETS["fast"]
    assert (run.agent.layer_norm, run.agent.utd, run.agent.demos.batch_share) == (
        preset["layer_norm"],
        preset["utd"],
        preset["demos_batch_share"],
    )
    assert run.agent.demos.reset_prob == preset["demos_reset_prob"]  # the experiment's demonstrations
    assert run.run_name.endswith("__demos__fast__return-bound-1")


def test_the_frontier_curriculum_moves_a_demonstrations_frontier_only_on_k_of_k_successes():
    """RFCL's per-demonstration frontier: starts drawn at it, a failure restarts the count, k
    successes in a row from demonstration i move its frontier (and only its) back by the stride."""
    from tsrl.agents.demo_resets import FRONTIER_STRIDE

    states = np.zeros((2, 51, 1))
    wrapped = DemoResets(
        gym.make("tsrl/UR5eReach-v0"), states, 1.0, 0, seed=0, frontier_k=3, first_success=np.array([30, 45])
    )
    assert {wrapped.frontier_step(0) for _ in range(200)} == set(range(30 - FRONTIER_STRIDE + 1, 31))
    for outcome in [True, True, False, True, True]:  # never 3 in a row
        wrapped.advance_frontier(0, outcome)
    assert wrapped.frontier == [30, 45] and wrapped.frontier_outcomes[0] == [True, True]
    wrapped.advance_frontier(0, True)  # the third in a row
    assert wrapped.frontier == [30 - FRONTIER_STRIDE, 45] and wrapped.frontier_outcomes == [[], []]
    for _ in range(3 * 20):  # never below the demonstration's first state
        wrapped.advance_frontier(1, True)
    assert wrapped.frontier == [30 - FRONTIER_STRIDE, 0]
    state = wrapped.curriculum_state()
    assert state["frontier"] == [30 - FRONTIER_STRIDE, 0]
    wrapped.close()


def test_a_frontier_episode_has_a_time_limit_that_grows_with_the_distance_to_the_end(reach_demos):
    from tsrl.agents.demo_files import load_demos
    from tsrl.agents.demo_resets import FRONTIER_MIN_STEPS, FRONTIER_TIME

    demos = load_demos(reach_demos)
    env = gym.make(REACH, obs="fs1")
    replay = gym.make(REACH, obs="fs1")
    states = replay_states(replay, demos, str(reach_demos))
    first = np.argmax(demos.is_success, axis=1) + 1
    wrapped = DemoResets(env, states, 1.0, 0, seed=0, frontier_k=2, first_success=first)
    assert wrapped.frontier == [int(f) for f in first]
    wrapped.frontier = [44] * len(first)  # as if moved there: an episode near the demonstration's end
    _, info = wrapped.reset(seed=1)
    _, step = info["demo_reset"]
    assert 42 <= step <= 44
    limit = min(50, max(FRONTIER_MIN_STEPS, FRONTIER_TIME * (50 - step)))
    lengths = 0
    truncated = terminated = False
    while not (terminated or truncated):
        *_, terminated, truncated, info = wrapped.step(np.zeros(3, dtype=np.float32))
        lengths += 1
    assert lengths == limit < 50 and truncated
    wrapped.close()
    replay.close()


def test_a_resumed_run_continues_its_frontiers(reach_demos, tmp_path, monkeypatch):
    from tsrl.agents.checkpoint import DEMO_RESETS, usable_checkpoint
    from tsrl.agents.training import resume, train

    demos = DemoConfig(path=str(reach_demos), reset_prob=1.0, reset_frontier_k=1)
    run_dir = train(tiny(total=200, demos=demos), tmp_path, progress_bar=False)
    checkpoint = usable_checkpoint(run_dir, True, for_training=True)
    assert checkpoint is not None and checkpoint.rng is not None
    saved = checkpoint.rng[DEMO_RESETS]["frontier"]
    seen: list[list[int]] = []  # the frontiers at the resumed run's first demonstration reset
    draw = DemoResets.frontier_step

    def recording(self: DemoResets, episode: int) -> int:
        seen.append(list(self.frontier))
        return draw(self, episode)

    monkeypatch.setattr(DemoResets, "frontier_step", recording)
    resume(run_dir, total_timesteps=300, progress_bar=False)
    assert seen and seen[0] == saved
