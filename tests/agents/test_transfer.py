"""A run's policy on another task (tsrl.agents.transfer, evaluation), swept perturbations, and
--init-from (tsrl.agents.init_from): the exact parameters and statistics come over; incompatible
sources are refused with one line and nothing written."""

from __future__ import annotations

import dataclasses
import io
import math
import pickle
import zipfile

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from training_helpers import tiny

from tsrl.agents.config import AgentConfig
from tsrl.agents.evaluation import Evaluator, eval_seeds, evaluate_run, evaluate_run_on
from tsrl.agents.factory import make_agent, make_vec_env
from tsrl.agents.init_from import INIT_FROM_RECORD, check_init_from, load_init
from tsrl.agents.training import train
from tsrl.agents.transfer import PERTURB_KEYS, base_task, eval_task, parse_perturb, perturbed, sweep
from tsrl.envs import TASK_ENV_ID
from tsrl.envs.tasks import RANDOMIZE_MAGNITUDES, RANDOMIZE_SCALES
from tsrl.exceptions import InvalidConfig

PANDA = "tsrl/PandaReach-v0"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A tiny trained UR5e reach run (fs1), shared by the tests that only read it."""
    return train(tiny(), tmp_path_factory.mktemp("source"), progress_bar=False)


class GoalSeeker:
    """A policy without networks: steps the TCP target toward the desired goal it is shown
    (achieved and desired goal are the TCP and marker positions in reach)."""

    def predict(self, batch, deterministic=True):
        return np.clip((batch["desired_goal"] - batch["achieved_goal"]) / 0.05, -1.0, 1.0), None


def _same(a, b) -> bool:
    """Two EvalResults equal field by field (NaN equal to NaN)."""
    pairs = zip(dataclasses.astuple(a), dataclasses.astuple(b), strict=True)
    return all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in pairs)


def _one_line(err) -> str:
    message = str(err.value)
    assert "\n" not in message
    return message


# -- evaluating on another task -------------------------------------------------------------------
def test_the_own_task_given_as_a_target_is_the_run_s_own_evaluation(run):
    own = evaluate_run(run, 4)
    again = evaluate_run(run, 4, env_id="tsrl/UR5eReach-v0")
    assert _same(own.result, again.result) and np.isfinite(own.result.mean_final_distance)
    assert again.task == "tsrl/UR5eReach-v0"


def test_a_ur5e_policy_runs_on_the_panda(run):
    out = evaluate_run(run, 4, env_id=PANDA)
    assert out.task == PANDA and out.result.episodes == 4
    own = evaluate_run(run, 4)
    assert out.result.mean_final_distance != own.result.mean_final_distance  # another arm, other episodes


def test_another_layout_is_refused_in_one_line_before_the_policy_loads(run, tmp_path):
    # A copy of the run without checkpoints: loading its policy would fail differently.
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "config.json").write_bytes((run / "config.json").read_bytes())
    with pytest.raises(InvalidConfig) as err:
        evaluate_run(bare, 2, env_id="tsrl/UR5ePickPlace-v0")
    message = _one_line(err)
    assert "tsrl/UR5ePickPlace-v0 does not match the layout of tsrl/UR5eReach-v0: goal row 0" in message
    with pytest.raises(InvalidConfig) as err:
        evaluate_run(run, 2, env_id=PANDA, task="x.toml")
    assert "not both" in _one_line(err)


def test_a_joint_space_policy_does_not_move_between_six_and_seven_joints():
    cfg = dataclasses.replace(tiny(), action="joint")
    from tsrl.agents.transfer import check_layout

    with pytest.raises(InvalidConfig) as err:
        check_layout(cfg, eval_task(cfg, PANDA))
    assert "action part 0 is joint steps (7 joints" in _one_line(err)


def test_success_is_counted_against_the_true_goal_under_a_goal_offset():
    cfg = tiny()
    task = perturbed(base_task(cfg.env_id), "goal_offset", 0.05)
    target = dataclasses.replace(eval_task(cfg), task=task)
    seeds = eval_seeds(3, 30)
    evaluator = Evaluator(cfg, seeds, target)
    result = evaluator.evaluate(GoalSeeker(), None)
    evaluator.close()
    shown, true, distance = [], [], []
    env = gym.make(TASK_ENV_ID, **target.env_kwargs(cfg))
    for seed in seeds:  # the same policy, counted one episode at a time
        obs, _ = env.reset(seed=seed)
        done = False
        while not done:
            action, _ = GoalSeeker().predict({k: v[None] for k, v in obs.items()})
            obs, _, terminated, truncated, info = env.step(action[0])
            done = terminated or truncated
        shown.append(info["is_success"])
        true.append(info["true_success"])
        distance.append(info["true_distance"])
    env.close()
    assert np.mean(shown) > np.mean(true)  # the offset goal is reached, the true one not always
    assert result.success_rate == np.mean(true)
    assert result.mean_final_distance == pytest.approx(np.mean(distance))


# -- sweeps ----------------------------------------------------------------------------------------
def test_a_sweep_sets_its_key_and_nothing_else():
    task = base_task("tsrl/UR5ePickPlace-v0")  # with an object: every key applies
    for key in PERTURB_KEYS:
        value = 2.0 if key in (*RANDOMIZE_SCALES, "joint_damping", "action_latency") else 0.01
        r = perturbed(task, key, value).randomize
        expected = (value, value) if key in (*RANDOMIZE_SCALES, "joint_damping", "action_latency") else value
        assert getattr(r, key) == expected
        others = {f.name for f in dataclasses.fields(r)} - {key}
        assert all(getattr(r, k) == getattr(task.randomize, k) for k in others)
    assert perturbed(task, "action_latency", 2).randomize.action_latency == (2, 2)  # exactly 2 periods
    assert all(isinstance(k, int) for k in perturbed(task, "action_latency", 2).randomize.latency_range)


def test_sweep_values_are_evaluated_on_the_same_episodes(run):
    cfg = tiny()
    tasks = sweep(eval_task(cfg), parse_perturb("servo_gain=1,0.25"))
    nominal, slow = evaluate_run_on(run, tasks, 3)
    assert _same(nominal.result, evaluate_run(run, 3).result)  # a scale of 1 is the nominal world
    assert slow.result.mean_final_distance != nominal.result.mean_final_distance
    assert slow.task == "tsrl/UR5eReach-v0 [servo_gain=0.25]"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("gains=1,2", "unknown perturbation key 'gains'; accepted: " + ", ".join(PERTURB_KEYS)),
        ("observation_noise=-0.01", "observation_noise = -0.01; accepted: values >= 0"),
        ("servo_gain", "expected KEY=V1,V2,..."),
        ("servo_gain=1,x", "'x' is not a number"),
        ("action_latency=0.5", "accepted: whole control periods"),
        ("servo_gain=1,1", "lists a value more than once"),
        ("servo_gain=0", "servo_gain = 0; accepted: values > 0"),  # a scale
        ("object_friction=-1", "object_friction = -1; accepted: values > 0"),
    ],
)
def test_bad_perturbations_are_one_line(text, expected):
    with pytest.raises(InvalidConfig) as err:
        parse_perturb(text)
    assert expected in _one_line(err)


@pytest.mark.parametrize(
    ("key", "value", "expected"),
    [
        ("action_latency", 50, "randomize.action_latency = [50, 50]; accepted: 0 to 49"),
        ("observation_noise", 0.2, f"accepted: 0 to {RANDOMIZE_MAGNITUDES['observation_noise']:g}"),
        ("tcp_offset", 0.2, f"accepted: 0 to {RANDOMIZE_MAGNITUDES['tcp_offset']:g}"),
    ],
)
def test_magnitudes_out_of_range_are_one_line_naming_the_key(key, value, expected):
    with pytest.raises(InvalidConfig) as err:
        sweep(eval_task(tiny()), parse_perturb(f"{key}={value}"))
    assert expected in _one_line(err) and f"perturbation {key}={value:g}" in str(err.value)


# -- --init-from -----------------------------------------------------------------------------------
def _policy_state(checkpoint) -> dict[str, th.Tensor]:
    """The policy's state dict as stored in the checkpoint's model.zip (read without stable-baselines3)."""
    with zipfile.ZipFile(checkpoint / "model.zip") as archive:
        return th.load(io.BytesIO(archive.read("policy.pth")), map_location="cpu", weights_only=True)


def test_init_from_loads_the_exact_parameters_and_normaliser_statistics(run, tmp_path):
    cfg = dataclasses.replace(tiny(), env_id=PANDA, init_from=str(run))
    assert check_init_from(cfg) is not None
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    before = {k: v.clone() for k, v in model.policy.state_dict().items()}
    load_init(cfg, tmp_path, model, venv)
    (checkpoint,) = sorted((run / "checkpoints").iterdir())[-1:]
    stored = _policy_state(checkpoint)
    loaded = model.policy.state_dict()
    assert stored.keys() == loaded.keys()
    for name, tensor in stored.items():
        assert th.equal(loaded[name], tensor), name
    assert any(not th.equal(before[k], stored[k]) for k in stored)  # the check could fail
    with open(checkpoint / "vecnormalize.pkl", "rb") as f:
        source_stats = pickle.load(f).obs_rms
    for key, rms in source_stats.items():
        assert np.array_equal(venv.obs_rms[key].mean, rms.mean)
        assert np.array_equal(venv.obs_rms[key].var, rms.var)
        assert venv.obs_rms[key].count == rms.count
    assert model.replay_buffer.size() == 0
    assert (tmp_path / INIT_FROM_RECORD).is_file()
    venv.close()


def test_a_fine_tuned_run_starts_from_its_source_and_is_named_so(run, tmp_path):
    cfg = dataclasses.replace(tiny(total=100), env_id=PANDA, init_from=str(run))
    out = train(cfg, tmp_path, progress_bar=False)
    assert out.name == "tsrl-PandaReach-v0__fs1__taskspace__ddpg__s0__init"
    (checkpoint,) = sorted((run / "checkpoints").iterdir())[-1:]
    assert str(checkpoint) in (out / INIT_FROM_RECORD).read_text()


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"agent": AgentConfig(algo="td3")}, "algo is 'ddpg' there, 'td3' here"),
        ({"agent": AgentConfig(net_arch=(64, 64))}, "net_arch is 256 256 there, 64 64 here"),
        ({"env_id": "tsrl/UR5ePickPlace-v0"}, "does not match the layout of tsrl/UR5eReach-v0"),
        ({"obs": "fs2"}, "observation row 5 is"),
    ],
)
def test_incompatible_sources_are_refused_in_one_line_with_nothing_written(run, tmp_path, change, expected):
    cfg = dataclasses.replace(tiny(), init_from=str(run), **change)
    with pytest.raises(InvalidConfig) as err:
        train(cfg, tmp_path / "out", progress_bar=False)
    message = _one_line(err)
    assert message.startswith(f"--init-from {run}") and expected in message
    assert not (tmp_path / "out").exists()


def test_a_folder_that_is_not_a_run_is_refused(tmp_path):
    with pytest.raises(InvalidConfig) as err:
        check_init_from(dataclasses.replace(tiny(), init_from=str(tmp_path)))
    assert "is not a run folder" in _one_line(err)
