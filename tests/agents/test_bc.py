"""Behaviour cloning as a learner (`--algo bc`): it fits a known linear demonstrator, its run folder
counts gradient steps (env steps 0), resumes bit for bit from a checkpoint, evaluates and exports like
any run; what cannot combine with it is refused in one line."""

from __future__ import annotations

import csv
import dataclasses
import shutil

import numpy as np
import pytest
import torch as th
from cli_runner import run_tsrl

import tsrl  # noqa: F401  (registers the environments)
from tsrl.agents import TrainConfig, resume, train
from tsrl.agents.bc import BehaviourCloning, with_dropout
from tsrl.agents.checkpoint import load_policy, usable_checkpoint
from tsrl.agents.config import AgentConfig, DemoConfig
from tsrl.agents.demo_files import save_demos
from tsrl.agents.demonstrators import record_demos
from tsrl.agents.evaluation import evaluate_run
from tsrl.agents.run_folder import checkpoint_dirs, read_progress
from tsrl.deploy.export import export_run
from tsrl.exceptions import InvalidConfig

REACH = "tsrl/UR5eReach-v0"
#: fs1's rows of positionDiff(tcp, target) in the observation vector (after position(tcp), position(target)).
DIFF = slice(6, 9)
#: The known demonstrator: a = GAIN * positionDiff(tcp, target), within [-1, 1] over the reach's goals.
GAIN = -2.0


@pytest.fixture(scope="module")
def linear_demos(tmp_path_factory):
    """24 scripted reach episodes (fs1) whose actions are replaced by the linear demonstrator's."""
    demos = record_demos(REACH, 24, obs="fs1", seed=0)
    linear = GAIN * demos.observation[:, :-1, DIFF]
    assert np.abs(linear).max() < 0.95  # inside tanh's range: a linear map the actor can fit
    path = tmp_path_factory.mktemp("bc") / "linear.npz"
    return save_demos(dataclasses.replace(demos, actions=linear.astype(demos.actions.dtype)), path)


def bc_config(path, steps: int = 3000, **agent) -> TrainConfig:
    return TrainConfig(
        env_id=REACH,
        obs="fs1",
        eval_freq=1000,
        eval_episodes=2,
        checkpoint_freq=1000,
        agent=AgentConfig(algo="bc", bc_steps=steps, demos=DemoConfig(path=str(path)), **agent),
    )


def test_bc_fits_a_known_linear_demonstrator(linear_demos, tmp_path):
    path = linear_demos
    run_dir = train(bc_config(path), tmp_path, progress_bar=False)
    checkpoint = usable_checkpoint(run_dir, True, for_training=False)
    assert checkpoint is not None
    model, normalizer = load_policy(checkpoint, BehaviourCloning)
    # States the demonstrator never showed: other seeds' scripted episodes.
    unseen = record_demos(REACH, 12, obs="fs1", seed=1)
    obs = {
        k: getattr(unseen, k)[:, :-1].reshape(-1, getattr(unseen, k).shape[-1]) for k in normalizer.obs_rms
    }
    actions, _ = model.predict(normalizer.normalize_obs(obs), deterministic=True)
    expected = GAIN * obs["observation"][:, DIFF]
    moving = np.linalg.norm(expected, axis=1) > 0.1  # on the way to the goal (most steps are at it)
    assert moving.sum() >= 20  # actions far from 0: the comparison can fail
    error = np.abs(actions - expected)
    assert error.mean() < 0.02, error.mean()
    assert error[moving].mean() < 0.05 and error.max() < 0.25, (error[moving].mean(), error.max())


def test_a_bc_run_counts_gradient_steps_resumes_bit_for_bit_evaluates_and_exports(linear_demos, tmp_path):
    path = linear_demos
    run_dir = train(bc_config(path, steps=2000), tmp_path / "a", progress_bar=False)
    rows = read_progress(run_dir)
    assert [r["gradient_steps"] for r in rows] == [0, 1000, 2000]
    assert {r["env_steps"] for r in rows} == {0} and {r["episodes"] for r in rows} == {0}
    assert [p.name for p in checkpoint_dirs(run_dir)] == ["step_0000001000", "step_0000002000"]
    # A run killed after its first checkpoint: the copy without the last one resumes to the same end.
    copy = tmp_path / "b" / run_dir.name
    shutil.copytree(run_dir, copy)
    shutil.rmtree(checkpoint_dirs(copy)[-1])
    resume(copy, progress_bar=False)
    for a, b in zip(
        *(load_policy(usable_checkpoint(d, True, False), BehaviourCloning)[0].actor.parameters()  # type: ignore[arg-type]
          for d in (run_dir, copy)),
        strict=True,
    ):  # fmt: skip
        assert th.equal(a, b)
    with open(copy / "progress.csv", newline="") as f:
        steps = [int(r["gradient_steps"]) for r in csv.DictReader(f)]
    assert steps == [0, 1000, 2000]  # the row after the checkpoint written once, not twice
    evaluation = evaluate_run(run_dir, 4, seed=0)
    assert evaluation.env_steps == 0 and 0 <= evaluation.result.success_rate <= 1
    out = export_run(run_dir, tmp_path / "export")  # export_run checks the ONNX actions against torch's
    assert (out / "policy.onnx").is_file()


def test_dropout_follows_each_hidden_activation_and_is_off_when_acting():
    mlp = th.nn.Sequential(
        th.nn.Linear(3, 8), th.nn.ReLU(), th.nn.Linear(8, 8), th.nn.ReLU(), th.nn.Linear(8, 2)
    )
    layers = [type(m).__name__ for m in with_dropout(mlp, 0.5)]
    assert layers == ["Linear", "ReLU", "Dropout", "Linear", "ReLU", "Dropout", "Linear"]
    net = with_dropout(mlp, 0.5).eval()
    x = th.ones(4, 3)
    assert th.equal(net(x), mlp(x))


@pytest.mark.parametrize(
    ("agent", "words"),
    [
        ({}, ["algo bc clones demonstrations", "--demos FILE"]),
        ({"demos": "demos.npz", "action_noise": 0.1}, ["action_noise 0.1", "accepted: 0.2"]),
        ({"demos": "demos.npz", "learner": "fast"}, ["learner 'fast'", "accepted: 'paper'"]),
        ({"demos": "demos.npz", "bc_steps": 0}, ["bc_steps", ">= 1"]),
    ],
)
def test_what_cannot_combine_with_bc_is_refused_in_one_line(agent, words):
    path = agent.pop("demos", None)
    with pytest.raises(InvalidConfig) as err:
        AgentConfig(algo="bc", demos=DemoConfig(path=path), **agent)
    for word in words:
        assert word in str(err.value)


def test_the_cli_refuses_bc_without_demonstrations_or_with_her_options(linear_demos, tmp_path):
    path = linear_demos
    for extra, word in [([], "--demos FILE"), (["--demos", str(path), "--her-strategy", "final"], "her")]:
        result = run_tsrl("train", "--env", REACH, "--algo", "bc", *extra, "--out-dir", str(tmp_path))
        assert result.returncode == 2, result.stderr
        assert word in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())
