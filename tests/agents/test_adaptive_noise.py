"""Adaptive explore noise (AgentConfig.adaptive_noise, tsrl.agents.acting_gate): off by default and the
run unchanged; on, the explore episodes are measured and their noise's scale halves while their
success is below NOISE_DOWN of the choice's, doubles back at NOISE_UP, within [NOISE_FLOOR, 1], each
change judged on a new window; the noise's draws are the same numbers scaled; it survives a resume;
bad values are one line."""

from __future__ import annotations

from dataclasses import replace as dataclasses_replace
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.noise import NormalActionNoise
from training_helpers import saved_reach_demos, scalar_steps

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import AgentConfig, TrainConfig, resume, train
from tsrl.agents.acting_gate import (
    CHOICE,
    EPISODE_KINDS,
    EXPLORE,
    MIN_EPISODES,
    NOISE_DOWN,
    NOISE_FLOOR,
    NOISE_UP,
    WINDOW,
    ActingGate,
    ScaledNoise,
)
from tsrl.agents.config import DemoConfig
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"


def _gate_measured(choice: float, adapt: bool = True) -> ActingGate:
    """A gate whose clone is measured (its WINDOW episodes done) and whose choice has WINDOW episodes
    at success `choice`, at the start of a cycle."""
    gate = ActingGate(adapt_noise=adapt)
    gate.measured[CHOICE] = [i < round(choice * WINDOW) for i in range(WINDOW)]
    gate.measured["clone"] = [True] * WINDOW
    return gate


def _explore(gate: ActingGate, wins: int, episodes: int) -> None:
    """Ends `episodes` explore episodes of which the first `wins` succeed (other kinds: a failure)."""
    done = 0
    while done < episodes:
        if gate.kind == EXPLORE:
            gate.end_episode(done < wins)
            done += 1
        else:
            gate.measured[CHOICE] = gate.measured[CHOICE][1:] + gate.measured[CHOICE][:1]  # kept as it is
            gate.episodes += 1


def test_the_noise_halves_below_the_share_and_is_judged_again_on_a_new_window():
    gate = _gate_measured(0.8)
    _explore(gate, 0, WINDOW - 1)
    assert gate.noise_scale == 1.0  # not a full window yet
    _explore(gate, 0, 1)
    assert gate.noise_scale == 0.5 and gate.measured[EXPLORE] == []
    below = int(np.ceil(NOISE_DOWN * 0.8 * WINDOW)) - 1  # just below 3/4 of the choice's 0.8
    _explore(gate, below, WINDOW)
    assert gate.noise_scale == 0.25
    _explore(gate, below + 1, WINDOW)  # at 3/4 and below 95 %: kept
    assert gate.noise_scale == 0.25 and len(gate.measured[EXPLORE]) == WINDOW


def test_the_noise_doubles_back_at_the_upper_share_up_to_its_configured_std():
    gate = _gate_measured(0.5)
    gate.noise_scale = 0.25
    _explore(gate, int(np.ceil(NOISE_UP * 0.5 * WINDOW)), WINDOW)
    assert gate.noise_scale == 0.5
    _explore(gate, WINDOW, WINDOW)
    assert gate.noise_scale == 1.0
    _explore(gate, 3 * WINDOW, 3 * WINDOW)
    assert gate.noise_scale == 1.0  # never above the configured std


def test_the_scale_stops_at_its_floor_and_waits_for_a_measured_choice():
    gate = _gate_measured(0.8)
    _explore(gate, 0, 10 * WINDOW)
    assert gate.noise_scale == NOISE_FLOOR
    unjudged = _gate_measured(0.0)  # a choice that never wins gives no share to keep
    _explore(unjudged, 0, 2 * WINDOW)
    assert unjudged.noise_scale == 1.0
    young = ActingGate(adapt_noise=True)
    young.measured[CHOICE] = [True] * (MIN_EPISODES - 1)
    _explore(young, 0, 2 * WINDOW)
    assert young.noise_scale == 1.0


def test_without_adaptation_the_explore_episodes_are_not_measured():
    gate = _gate_measured(0.8, adapt=False)
    _explore(gate, 0, 3 * WINDOW)
    assert EXPLORE not in gate.measured and gate.noise_scale == 1.0
    assert EPISODE_KINDS.count(EXPLORE) == 2


def test_scaled_noise_draws_the_same_numbers_scaled():
    base = NormalActionNoise(np.zeros(3), 0.1 * np.ones(3))
    np.random.seed(3)
    plain = [base() for _ in range(4)]
    np.random.seed(3)
    scaled = ScaledNoise(base, 0.25)
    np.testing.assert_array_equal([scaled() for _ in range(4)], [0.25 * p for p in plain])


@pytest.fixture(scope="module")
def reach_demos(tmp_path_factory) -> Path:
    return saved_reach_demos(tmp_path_factory, 8)


def _fast(path: Path, **agent: object) -> TrainConfig:
    return TrainConfig(
        env_id=REACH, obs="fs1", total_timesteps=400, eval_freq=200, eval_episodes=2, checkpoint_freq=200,
        agent=AgentConfig(learner="fast", batch_size=64, bc_steps=300, demos=DemoConfig(path=str(path)), **agent),
    )  # fmt: skip


def test_a_run_with_adaptive_noise_is_named_logs_its_scale_and_resumes_with_it(reach_demos, tmp_path):
    plain, adaptive = _fast(reach_demos), _fast(reach_demos, adaptive_noise=True)
    assert adaptive.run_name == f"{plain.run_name}__adaptive-noise"
    run_dir = train(dataclasses_replace(adaptive, total_timesteps=200), tmp_path, progress_bar=False)
    resume(run_dir, total_timesteps=400, progress_bar=False)
    assert max(scalar_steps(run_dir, "gate/noise_scale")) > 200  # the resumed run's gate adapts too


@pytest.mark.parametrize("value", ["yes", 1])
def test_a_bad_value_is_one_line(value):
    with pytest.raises(InvalidConfig, match=r"^adaptive_noise .*accepted: true or false") as err:
        AgentConfig(adaptive_noise=value)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_adaptive_noise_without_the_fast_learners_gate_is_refused(reach_demos):
    for agent in (
        {"learner": "paper", "demos": DemoConfig(path=str(reach_demos))},
        {"learner": "fast"},
        {"learner": "fast", "demos": DemoConfig(path=str(reach_demos)), "action_noise": 0.0},
    ):
        with pytest.raises(
            InvalidConfig, match=r"^adaptive_noise adapts the fast learner's explore noise"
        ) as err:
            AgentConfig(adaptive_noise=True, **agent)  # type: ignore[arg-type]
        assert "\n" not in str(err.value)
