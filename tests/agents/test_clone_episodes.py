"""The clone measured on more episodes (AgentConfig.clone_episodes, tsrl.agents.acting_gate): by default
the gate as before (20, the choice's window; run names unchanged); with N the clone's place in the cycle
stays a clone episode until N are measured, all of which count against the choice's last WINDOW; the
setting reaches the gate of a new and of a resumed run; bad values are one line."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace
from pathlib import Path

import pytest
from stable_baselines3 import TD3
from training_helpers import fast_reach, saved_reach_demos

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, make_agent, make_vec_env, resume, train
from tsrl.agents.acting_gate import EPISODE_KINDS, EXPLORE, MIN_EPISODES, WINDOW, ActingGate, GatedTD3
from tsrl.agents.checkpoint import MODEL, usable_checkpoint
from tsrl.agents.config import CLONE_EPISODES, DemoConfig
from tsrl.agents.reference import CHOICE, CLONE
from tsrl.exceptions import InvalidConfig


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def _fast(path: Path, **agent: object) -> TrainConfig:
    """fast_reach with an evaluation and a checkpoint every 200 env steps."""
    return dataclasses_replace(fast_reach(path, **agent), eval_freq=200, eval_episodes=2, checkpoint_freq=200)


def test_the_default_is_the_gate_as_before():
    assert AgentConfig().clone_episodes == CLONE_EPISODES == WINDOW == ActingGate().clone_episodes


def test_the_clone_is_measured_on_all_its_episodes_then_its_place_explores():
    n = 3 * WINDOW
    gate = ActingGate(clone_episodes=n)
    kinds = []
    while len(gate.measured[CLONE]) < n:
        kinds.append(gate.kind)
        # The clone succeeds on its last WINDOW episodes only; the choice on every other of its own.
        clone_wins = len(gate.measured[CLONE]) >= n - WINDOW
        gate.end_episode(clone_wins if gate.kind == CLONE else gate.episodes % 8 == 1)
    assert kinds == list(EPISODE_KINDS) * n  # a clone episode in every cycle until n are measured
    assert gate.success(CLONE) == WINDOW / n  # all n count, not the last WINDOW (which all won)
    assert len(gate.measured[CHOICE]) == WINDOW and gate.success(CHOICE) == 0.5  # the choice's window
    assert gate.choice_acts  # 0.5 against 1/3 (against the clone's last WINDOW, 1.0, it would not)
    gate.measured[CHOICE] = [True] * 6 + [False] * (WINDOW - 6)
    assert not gate.choice_acts  # 0.3 against 1/3
    kinds = []
    for _ in range(2 * len(EPISODE_KINDS)):
        kinds.append(gate.kind)
        gate.end_episode(True)
    assert CLONE not in kinds and kinds[3] == EXPLORE  # measured: its place explores
    assert len(gate.measured[CLONE]) == n and gate.success(CLONE) == WINDOW / n


def test_the_setting_reaches_the_gate_of_a_new_and_of_a_resumed_run(reach_demos, tmp_path):
    plain, more = _fast(reach_demos), _fast(reach_demos, clone_episodes=2 * WINDOW)
    assert more.run_name == f"{plain.run_name}__clone-episodes-{2 * WINDOW}"
    model = make_agent(more, make_vec_env(more))
    assert isinstance(model, GatedTD3) and model.gate.clone_episodes == 2 * WINDOW
    run_dir = train(dataclasses_replace(more, total_timesteps=200), tmp_path, progress_bar=False)
    resume(run_dir, total_timesteps=400, progress_bar=False)
    checkpoint = usable_checkpoint(run_dir, normalized=True, for_training=False)
    assert checkpoint is not None and checkpoint.state.env_steps == 400
    loaded = TD3.load(
        checkpoint.path / MODEL,
        custom_objects={"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1},
    )
    assert loaded.gate.clone_episodes == 2 * WINDOW  # type: ignore[attr-defined]


@pytest.mark.parametrize("value", [MIN_EPISODES - 1, 0, 12.5, 20.0, "many", True])
def test_a_bad_count_is_one_line(reach_demos, value):
    with pytest.raises(InvalidConfig, match=rf"^clone_episodes must be an integer >= {MIN_EPISODES}") as err:
        AgentConfig(learner="fast", demos=DemoConfig(path=str(reach_demos)), clone_episodes=value)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_more_clone_episodes_without_the_fast_learners_gate_are_refused(reach_demos):
    for agent in ({"learner": "paper", "demos": DemoConfig(path=str(reach_demos))}, {"learner": "fast"}):
        with pytest.raises(
            InvalidConfig, match=r"^clone_episodes 40 sets how long .* accepted without them: 20$"
        ):
            AgentConfig(clone_episodes=40, **agent)  # type: ignore[arg-type]
