"""A task's `previous_actions`: the observation ends with the policy's last n actions (newest first,
zeros at reset) and nothing else changes; under action latency the newest one is the action still in
flight; HER relabelling leaves the rows alone; the layout check and export tell the tasks apart."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tsrl.envs.base import TaskEnv
from tsrl.envs.layout import check_same_layout, layout
from tsrl.envs.observations import PREVIOUS_ACTIONS
from tsrl.envs.tasks import Randomize, load_task
from tsrl.exceptions import InvalidConfig

PICK = "UR5eBasePickPlace-v0"


def _env(n: int, **randomize) -> TaskEnv:
    task = load_task(PICK)
    return TaskEnv(dataclasses.replace(task, previous_actions=n, randomize=Randomize(**randomize)))


def test_the_observation_ends_with_the_last_actions_newest_first_and_nothing_else_changes():
    plain, history = _env(0), _env(2)
    k = history.action_space.shape[0]
    base_dim = plain.observation_space["observation"].shape[0]
    assert history.observation_space["observation"].shape == (base_dim + 2 * k,)
    assert history.observation_structure[PREVIOUS_ACTIONS] == slice(base_dim, base_dim + 2 * k)
    a, _ = plain.reset(seed=4)
    b, _ = history.reset(seed=4)
    np.testing.assert_array_equal(b["observation"][base_dim:], np.zeros(2 * k))
    actions = np.random.default_rng(0).uniform(-1, 1, (5, k)).astype(np.float32)
    for t, action in enumerate(actions):
        a, ra, *_ = plain.step(action)
        b, rb, *_ = history.step(action)
        assert b["observation"][:base_dim].tobytes() == a["observation"].tobytes()
        for key in ("achieved_goal", "desired_goal"):
            assert b[key].tobytes() == a[key].tobytes()
        assert ra == rb
        older = actions[t - 1] if t >= 1 else np.zeros(k)
        np.testing.assert_array_equal(b["observation"][base_dim:], np.concatenate([action, older]))
    b, _ = history.reset(seed=5)
    np.testing.assert_array_equal(b["observation"][base_dim:], np.zeros(2 * k))


def test_under_one_period_of_latency_the_newest_row_is_the_action_applied_next():
    late = _env(1, action_latency=(1, 1))
    k = late.action_space.shape[0]
    late.reset(seed=0)
    actions = np.random.default_rng(1).uniform(-1, 1, (4, k)).astype(np.float32)
    for action in actions:
        obs, *_ = late.step(action)
        pending = late._perturb._latency[0]
        np.testing.assert_array_equal(obs["observation"][-k:], pending)
        np.testing.assert_array_equal(pending, action)


def test_noise_stays_out_of_the_action_rows_and_relabelling_leaves_them_alone():
    env = _env(2, observation_noise=0.01)
    k = env.action_space.shape[0]
    rng = np.random.default_rng(2)
    env.reset(seed=2)
    for _ in range(3):
        action = rng.uniform(-1, 1, k).astype(np.float32)
        obs, *_ = env.step(action)
        np.testing.assert_array_equal(obs["observation"][-2 * k : -k], action)
    for _ in range(3):
        goal = obs["desired_goal"] + rng.normal(0, 0.05, obs["desired_goal"].shape)
        relabelled = env.relabel(obs, goal)
        moved = env.move_target(goal)
        np.testing.assert_allclose(relabelled["observation"], moved["observation"], atol=1e-12)
        np.testing.assert_array_equal(relabelled["observation"][-2 * k :], obs["observation"][-2 * k :])


def test_the_layout_check_tells_a_task_with_previous_actions_from_one_without():
    with_rows, without = _env(1), _env(0)
    check_same_layout(layout(with_rows), layout(_env(1)), "a", "b")
    k = with_rows.action_space.shape[0]
    with pytest.raises(InvalidConfig, match=f"{PREVIOUS_ACTIONS} \\({k} values\\)"):
        check_same_layout(layout(with_rows), layout(without), "with", "without")


@pytest.mark.parametrize(("value", "shown"), [("-1", "-1"), ("50", "50"), ("true", "True"), ("1.5", "1.5")])
def test_bad_previous_actions_are_one_line_naming_the_file_and_key(tmp_path, value, shown):
    path = tmp_path / "bad.toml"
    path.write_text(f"previous_actions = {value}\n" + load_task(PICK).source.read_text())
    with pytest.raises(InvalidConfig) as err:
        load_task(path)
    text = str(err.value)
    assert "\n" not in text and str(path) in text and "previous_actions" in text


def test_a_restored_state_brings_back_the_previous_actions_with_the_physics():
    source, restored = _env(2), _env(2)
    k = source.action_space.shape[0]
    source.reset(seed=6)
    actions = np.random.default_rng(3).uniform(-1, 1, (4, k)).astype(np.float32)
    for action in actions[:3]:
        obs, *_ = source.step(action)
    restored.reset(seed=7)  # another episode: other physics, zero previous actions
    again = restored.restore_state(source.get_state())
    for key in obs:
        assert again[key].tobytes() == obs[key].tobytes(), key
    np.testing.assert_array_equal(again["observation"][-2 * k :], np.concatenate([actions[2], actions[1]]))
    a, *_ = source.step(actions[3])
    b, *_ = restored.step(actions[3])  # and goes on as the source does
    assert b["observation"].tobytes() == a["observation"].tobytes()
    with pytest.raises(ValueError, match=r"get_state's"):
        _env(0).restore_state(source.get_state())  # a state with previous actions, a task without
