"""The bad-input and fault battery (issue 53): each input or fault a new user tried is refused before any
work starts, in one line naming the file or option, the key, the value and what is accepted (exit 2 at
the command line), or handled (a signal stops the work and leaves a checkpoint to resume from).

Signal tests never wait on time: a signal is sent once a file or line shows where the process is, or by
the process to itself at the point under test, and the test waits for the exit with a generous timeout.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from cli_runner import REPO, run_tsrl
from training_helpers import tiny

from tsrl.agents import evaluation
from tsrl.agents.run_folder import read_progress
from tsrl.agents.training import TrainingInterrupted, resume, train
from tsrl.envs.tasks import builtin_task_path
from tsrl.experiments.config import load_experiment
from tsrl.experiments.evaluations import read_evaluations
from tsrl.experiments.runner import checkpoint_steps


def _one_line(result: subprocess.CompletedProcess) -> str:
    """The single stderr line of a refused command (exit 2, nothing on stdout)."""
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("tsrl: error: ")
    return line


# -- signals -------------------------------------------------------------------------------------------
def test_sigterm_during_an_evaluation_stops_it_and_the_checkpoint_resumes(tmp_path, monkeypatch):
    """SIGTERM arriving while an evaluation runs stops it before its next step (it never waits for every
    episode to end); the run leaves a checkpoint, no row of the dropped evaluation, and resumes from it."""
    evaluate = evaluation.Evaluator.evaluate
    sent = []

    def signalled(self, *args, **kwargs):  # the signal lands inside the first evaluation
        if not sent:
            sent.append(os.getpid())
            os.kill(os.getpid(), signal.SIGTERM)
        return evaluate(self, *args, **kwargs)

    monkeypatch.setattr(evaluation.Evaluator, "evaluate", signalled)
    cfg = tiny()
    with pytest.raises(TrainingInterrupted) as stop:
        train(cfg, tmp_path, progress_bar=False)
    run_dir = tmp_path / cfg.run_name
    assert stop.value.signum == signal.SIGTERM and sent
    assert read_progress(run_dir) == [] and (run_dir / "checkpoints").is_dir()  # the evaluation dropped
    assert list(tmp_path.iterdir()) == [run_dir]  # nothing written outside the run's own folder
    monkeypatch.undo()
    resume(run_dir, progress_bar=False)
    rows = read_progress(run_dir)
    assert [int(r["env_steps"]) for r in rows] == [0, 100, 200]  # step 0 evaluated again on resume
    assert checkpoint_steps(run_dir) == cfg.total_timesteps


def _signal_at_call(monkeypatch, owner: type, name: str, n: int) -> list[int]:
    """SIGTERM to this process inside the n-th call of owner.name; returns the list of calls so far."""
    original = getattr(owner, name)
    calls: list[int] = []

    def signalled(self, *args, **kwargs):
        calls.append(1)
        if len(calls) == n:
            os.kill(os.getpid(), signal.SIGTERM)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(owner, name, signalled)
    return calls


def _checkpointed_model(run_dir: Path):
    from stable_baselines3 import DDPG

    from tsrl.agents.checkpoint import load_checkpoint, usable_checkpoint
    from tsrl.agents.factory import make_vec_env
    from tsrl.agents.run_folder import load_config

    cfg = load_config(run_dir)
    checkpoint = usable_checkpoint(run_dir, cfg.agent.normalize, for_training=True)
    assert checkpoint is not None
    venv = make_vec_env(cfg)
    return load_checkpoint(checkpoint, DDPG, venv, None), checkpoint


def test_sigterm_during_an_update_stops_it_before_its_next_gradient_step(tmp_path, monkeypatch):
    """A signal inside an update (10 gradient steps here; 400 on the stack) ends it before the next
    gradient step applies anything: the checkpoint counts the 3 steps applied, not 10, and resumes."""
    from tsrl.agents.her import FeatureHerReplayBuffer

    calls = _signal_at_call(monkeypatch, FeatureHerReplayBuffer, "sample", 4)  # the 4th gradient step's batch
    cfg = tiny()
    with pytest.raises(TrainingInterrupted):
        train(cfg, tmp_path, progress_bar=False)
    monkeypatch.undo()
    run_dir = tmp_path / cfg.run_name
    assert len(calls) == 4  # no gradient step started after the signal
    model, checkpoint = _checkpointed_model(run_dir)
    assert model._n_updates == 3 and cfg.agent.gradient_steps == 10
    assert checkpoint.state.env_steps == model.num_timesteps > cfg.agent.learning_starts
    resume(run_dir, progress_bar=False)
    assert checkpoint_steps(run_dir) == cfg.total_timesteps


def test_sigterm_during_a_rollout_stops_after_the_env_step_in_progress(tmp_path, monkeypatch):
    """A signal inside an episode's env step stops the rollout there: that step is neither stored nor
    counted, the episode so far is kept as one cut short (its last transition a time limit), and the
    checkpoint resumes."""
    from stable_baselines3.common.vec_env import DummyVecEnv

    cfg = tiny()
    _signal_at_call(monkeypatch, DummyVecEnv, "step_wait", 130)  # inside the third episode (50 steps each)
    with pytest.raises(TrainingInterrupted) as stop:
        train(cfg, tmp_path, progress_bar=False)
    monkeypatch.undo()
    run_dir = tmp_path / cfg.run_name
    assert stop.value.env_steps == 129
    model, checkpoint = _checkpointed_model(run_dir)
    buffer = model.replay_buffer
    assert checkpoint.state.env_steps == model.num_timesteps == buffer.pos == 129
    assert buffer.dones[128, 0] and buffer.timeouts[128, 0] and not buffer.dones[127, 0]
    assert buffer.ep_length[100:129, 0].tolist() == [29] * 29  # the cut episode is a whole one for HER
    resume(run_dir, progress_bar=False)
    # Rollouts are whole episodes again from the resume on: the budget is reached in the one under way.
    assert cfg.total_timesteps <= checkpoint_steps(run_dir) < cfg.total_timesteps + 2 * 50


def _experiment_file(tmp_path: Path) -> Path:
    definition = tmp_path / "long.toml"
    definition.write_text(
        'obs = ["fs1"]\nseeds = [0]\ntotal_timesteps = 1000000\neval_freq = 100\neval_episodes = 2\n'
        "[agent]\nlearning_starts = 100\n"
    )
    return definition


#: `tsrl` as a shell's background job starts it: SIGINT ignored, inherited from the shell.
_TSRL_IN_BACKGROUND = [
    sys.executable,
    "-c",
    (
        "import runpy, signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); sys.argv[0] = 'tsrl'; "
        "runpy.run_module('tsrl.cli', run_name='__main__', alter_sys=True)"
    ),
]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_background_experiment_stops_on_sigint_and_sigterm_with_128_plus_the_signal(tmp_path, sig):
    """Started as a shell's background job (SIGINT inherited ignored), `tsrl experiment` still stops on
    SIGINT (exit 130) and on SIGTERM (exit 143), once it has started (experiment.json written)."""
    out = tmp_path / "results"
    proc = subprocess.Popen(
        [*_TSRL_IN_BACKGROUND, "experiment", str(_experiment_file(tmp_path)), "--out-dir", str(out),
         "--workers", "1", "--no-report"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=REPO, start_new_session=True,
    )  # fmt: skip
    try:
        while not (out / "long" / "experiment.json").is_file():
            assert proc.poll() is None, proc.communicate()[1]
        proc.send_signal(sig)
        stderr = proc.communicate(timeout=180)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # it and its workers (its own session)
            proc.communicate()
    assert proc.returncode == 128 + sig, stderr
    assert stderr.splitlines()[-1] == "tsrl experiment: interrupted; run it again to resume"


# -- tracebacks: one line instead ----------------------------------------------------------------------
def test_evaluate_perturb_out_in_a_missing_folder_is_refused_before_the_evaluation(tmp_path):
    out = tmp_path / "no" / "such" / "x.csv"
    line = _one_line(run_tsrl("evaluate", str(tmp_path), "--perturb", "servo_gain=1", "--out", str(out)))
    assert f"--out {out}: no writable folder {out.parent}" in line and "existing folder" in line


# -- misleading messages -------------------------------------------------------------------------------
def test_init_from_another_observation_names_both_layouts():
    """Two runs on one task: the message tells them apart by observation (it said "X does not match X")."""
    from tsrl.agents.transfer import check_run_layouts
    from tsrl.exceptions import InvalidConfig

    source, new = tiny(), dataclasses.replace(tiny(), obs="baseline")
    with pytest.raises(InvalidConfig) as err:
        check_run_layouts(source, new)
    (line,) = str(err.value).splitlines()
    assert line.startswith(
        "tsrl/UR5eReach-v0 (observation baseline, action taskspace) does not match the layout of "
        "tsrl/UR5eReach-v0 (observation fs1, action taskspace): observation row 1"
    )


# -- found late: refused when the experiment loads -------------------------------------------------------
def test_two_task_files_of_one_file_name_in_one_experiment_are_refused_when_it_loads(tmp_path):
    reach = builtin_task_path("UR5eReach-v0").read_text()
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "reach.toml").write_text(reach)
    definition = tmp_path / "two.toml"
    definition.write_text('env = ["a/reach.toml", "b/reach.toml"]\nobs = ["fs1"]\ntotal_timesteps = 100\n')
    out = tmp_path / "results"
    line = _one_line(run_tsrl("experiment", str(definition), "--out-dir", str(out)))
    assert line.startswith(f"tsrl: error: {definition}: env ") and "give one run folder name" in line
    assert "task-reach__fs1" in line and "distinct file names" in line
    assert not out.exists()


def test_a_changed_definition_is_refused_and_experiment_json_kept(tmp_path):
    """A run folder made by the old definition: the new one is refused before anything is written."""
    definition = tmp_path / "grow.toml"
    definition.write_text('obs = ["fs1"]\ntotal_timesteps = 100\neval_episodes = 2\n')
    exp = load_experiment(definition, check_envs=False)
    exp_dir = tmp_path / "results" / "grow"
    (run,) = exp.runs(exp_dir.resolve())
    (exp_dir / run.run_name).mkdir(parents=True)
    (exp_dir / run.run_name / "config.json").write_text(json.dumps(run.to_dict()))
    (exp_dir / "experiment.json").write_text(json.dumps(exp.to_dict()))
    before = {p: p.read_bytes() for p in exp_dir.rglob("*") if p.is_file()}
    definition.write_text('obs = ["fs1"]\ntotal_timesteps = 100\neval_episodes = 3\n')
    line = _one_line(run_tsrl("experiment", str(definition), "--out-dir", str(tmp_path / "results")))
    assert f"run folder {exp_dir / run.run_name} holds a run of another config" in line
    assert "eval_episodes: 2 there, 3 here" in line and "experiment.json kept" in line
    assert {p: p.read_bytes() for p in exp_dir.rglob("*") if p.is_file()} == before


# -- damaged result files: one line from tsrl report ---------------------------------------------------
@pytest.fixture(scope="module")
def finished_run(tmp_path_factory) -> Path:
    """A tiny run at its budget (seconds), copied by each test that damages one of its files."""
    return train(tiny(), tmp_path_factory.mktemp("finished"), progress_bar=False)


def _results_with(finished_run: Path, tmp_path: Path) -> Path:
    results = tmp_path / "results"
    shutil.copytree(finished_run, results / finished_run.name)
    return results


def test_report_refuses_a_progress_row_cut_short(finished_run, tmp_path):
    results = _results_with(finished_run, tmp_path)
    progress = results / finished_run.name / "progress.csv"
    text = progress.read_text()
    progress.write_text(text[: text.rstrip("\n").rfind(",")] + "\n")  # the last row loses its last cell
    line = _one_line(run_tsrl("report", str(results)))
    rows = len(text.strip().splitlines())
    assert f"{progress}: row {rows} has 10 cells, the header 11 columns (cut short" in line
    assert "accepted: complete rows" in line


@pytest.mark.parametrize(("text", "why"), [("", "not JSON"), ("[1, 2]", "a JSON list")])
def test_report_refuses_an_empty_or_foreign_experiment_json(finished_run, tmp_path, text, why):
    results = _results_with(finished_run, tmp_path)
    (results / "experiment.json").write_text(text)
    line = _one_line(run_tsrl("report", str(results)))
    assert f"{results / 'experiment.json'}: {why}" in line and "accepted: the JSON object" in line


def test_report_refuses_a_corrupt_evaluations_csv(finished_run, tmp_path):
    from tsrl.experiments.evaluations import EVAL_COLUMNS

    results = _results_with(finished_run, tmp_path)
    row = {k: "" for k in EVAL_COLUMNS} | {"seed": "zero", "env_steps": "200", "episodes": "2"}
    (results / "evaluations.csv").write_text(",".join(EVAL_COLUMNS) + "\n" + ",".join(row.values()) + "\n")
    line = _one_line(run_tsrl("report", str(results)))
    assert f"{results / 'evaluations.csv'}: row 2: seed = 'zero'; accepted: a whole number" in line


# -- overflow and NaN in a robot's model -----------------------------------------------------------------
@pytest.mark.parametrize(
    ("option", "words"),
    [
        ('timestep="nan"', '<option timestep="nan">; accepted: finite numbers'),
        ('timestep="-0.002"', '<option timestep="-0.002">; accepted: > 0 s'),
        ('timestep="0.002" gravity="0 0 inf"', '<option gravity="0 0 inf">; accepted: finite numbers'),
    ],
)
def test_a_robot_model_with_a_nan_or_bad_option_is_one_line(tmp_path, option, words):
    from test_robot_check import ARM_XML, ROBOT_TOML

    (tmp_path / "arm.xml").write_text(ARM_XML.replace('timestep="0.002"', option))
    robot = tmp_path / "arm.toml"
    robot.write_text(ROBOT_TOML)
    result = run_tsrl("robot", "check", str(robot), "--no-images")
    assert result.returncode == 2 and result.stdout == "" and "Traceback" not in result.stderr
    last = result.stderr.strip().splitlines()[
        -1
    ]  # MuJoCo's own "XML contains a 'NaN'" warning may precede it
    assert last == f"tsrl: error: {robot}: the model's {words}"


def test_sigterm_during_an_experiments_evaluation_arms_ends_their_workers(tmp_path):
    """SIGTERM while [[evaluate]] arms run on worker processes: the running evaluations end at once (the
    rows written so far stay; a later call evaluates the rest) instead of being waited for (here for
    minutes: the slow arm's episodes are 10,000 steps long)."""
    reach = builtin_task_path("UR5eReach-v0").read_text()
    (tmp_path / "long.toml").write_text(reach.replace("episode_steps = 50", "episode_steps = 10000"))
    definition = tmp_path / "arms.toml"
    definition.write_text(
        'obs = ["fs1"]\nseeds = [0]\ntotal_timesteps = 200\neval_freq = 100\neval_episodes = 2\n'
        "checkpoint_freq = 100\n[agent]\nlearning_starts = 100\ngradient_steps = 10\nbatch_size = 64\n\n"
        '[[evaluate]]\nname = "quick"\narm = "fs1"\nenv = "tsrl/UR5eReach-v0"\nepisodes = 2\n\n'
        '[[evaluate]]\nname = "slow"\narm = "fs1"\nenv = "long.toml"\nepisodes = 50\n'
    )
    exp_dir = tmp_path / "results" / "arms"
    (run,) = load_experiment(definition, check_envs=False).runs(exp_dir.resolve())
    train(run, exp_dir, progress_bar=False)  # finished: the experiment goes straight to its two arms
    proc = subprocess.Popen(
        [sys.executable, "-m", "tsrl.cli", "experiment", str(definition), "--out-dir", str(tmp_path / "results"),
         "--workers", "2", "--no-report"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=REPO, start_new_session=True,
    )  # fmt: skip
    try:
        assert proc.stderr is not None
        while not proc.stderr.readline().startswith("evaluated "):  # the quick arm done, the slow one running
            assert proc.poll() is None
        proc.send_signal(signal.SIGTERM)
        stderr = proc.communicate(timeout=180)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert stderr.splitlines()[-1] == "tsrl experiment: interrupted; run it again to resume"
    labels = {row["label"] for row in read_evaluations(exp_dir / "evaluations.csv")}
    assert "quick" in labels and "slow" not in labels  # the rows kept so far stay
