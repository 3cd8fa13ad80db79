"""Tiny experiments trained for real: the local pool (killed, resumed, a failing run, re-run, report),
a local Ray instance, and the CLI's error paths.

Each scenario is one test (pytest-xdist may spread tests over processes; a scenario's steps build on
each other). Runs are 300 env steps: 100 random, then updates every two episodes.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_runner import REPO, TSRL_WITH_CTRL_C, run_tsrl

from tsrl.agents.demo_files import load_demos, sha256
from tsrl.agents.run_folder import check_not_locked, latest_checkpoint, read_state
from tsrl.exceptions import InvalidConfig
from tsrl.experiments.aggregate import RESULT_COLUMNS, write_report
from tsrl.experiments.config import Comparison, load_experiment
from tsrl.experiments.pool import run_experiment

TINY = """
description = "Two presets, two seeds, seconds each."
obs = ["fs1", "baseline"]
seeds = [0, 1]
total_timesteps = 300
eval_freq = 100
eval_episodes = 2
checkpoint_freq = 100

[agent]
learning_starts = 100
gradient_steps = 10
batch_size = 64
"""
EXPECTED_ROWS = [(0, 0), (100, 2), (200, 4), (300, 6)]  # (env steps, episodes) of each run's evaluations


def progress(run_dir: Path) -> list[tuple[int, int]]:
    with open(run_dir / "progress.csv", newline="") as f:
        return [(int(r["env_steps"]), int(r["episodes"])) for r in csv.DictReader(f)]


def checkpoint_at(run_dir: Path) -> int:
    checkpoint = latest_checkpoint(run_dir)
    return read_state(checkpoint).env_steps if checkpoint else 0


def test_local_pool_resumes_killed_runs_reports_a_failure_skips_finished_runs_and_reports(tmp_path):
    definition = tmp_path / "tiny.toml"
    definition.write_text(TINY)
    exp = load_experiment(definition)
    exp_dir = tmp_path / "results" / "tiny"
    fs1_s0, baseline_s0, fs1_s1, baseline_s1 = (exp_dir / c.run_name for c in exp.runs())

    # A run whose only checkpoint is damaged (an empty folder): that run must fail, alone. (A folder of
    # another config refuses the whole experiment before it starts: tests/test_fault_battery.py.)
    (baseline_s1 / "checkpoints" / "step_100").mkdir(parents=True)
    (baseline_s1 / "config.json").write_text(json.dumps(exp.runs()[3].to_dict()))

    # 1. `tsrl experiment` killed (SIGKILL, whole process group) once a run has a mid-way checkpoint.
    proc = subprocess.Popen(
        [sys.executable, "-m", "tsrl.cli", "experiment", str(definition), "--out-dir", str(tmp_path / "results"),
         "--workers", "2", "--no-report"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not any(0 < checkpoint_at(d) < 300 for d in (fs1_s0, baseline_s0, fs1_s1)):
        assert proc.poll() is None and time.monotonic() < deadline, "no mid-way checkpoint"
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    killed = {d.name: checkpoint_at(d) for d in (fs1_s0, baseline_s0, fs1_s1) if 0 < checkpoint_at(d) < 300}
    assert killed

    # 2. Running it again resumes the killed runs; the failing run is reported and the others finish.
    log = io.StringIO()
    outcomes = {o.run_name: o for o in run_experiment(exp, tmp_path / "results", workers=2, stream=log)}
    for name, at in killed.items():
        assert outcomes[name].status == "resumed", (name, at, outcomes[name])
    for run_dir in (fs1_s0, baseline_s0, fs1_s1):
        assert progress(run_dir) == EXPECTED_ROWS  # counters continued: each evaluation once, none lost
        assert checkpoint_at(run_dir) == 300 and outcomes[run_dir.name].env_steps == 300
        assert not (run_dir / "error.txt").exists()
    failed = outcomes[baseline_s1.name]
    assert failed.status == "failed" and "no usable checkpoint" in failed.error
    assert "Traceback" in (baseline_s1 / "error.txt").read_text()
    assert "failed" in log.getvalue() and "4/4 runs" in log.getvalue()
    assert json.loads((exp_dir / "experiment.json").read_text())["obs"] == ["fs1", "baseline"]

    # 3. Re-running skips finished runs without starting a worker and leaves their folders untouched.
    finished = dataclasses.replace(exp, obs=("fs1",))  # the failed baseline run would be retried
    stamps = {d: (d / "progress.csv").stat().st_mtime_ns for d in (fs1_s0, fs1_s1)}
    outcomes = {
        o.run_name: o.status for o in run_experiment(finished, tmp_path / "results", stream=io.StringIO())
    }
    assert outcomes == {fs1_s0.name: "skipped", fs1_s1.name: "skipped"}
    assert stamps == {d: (d / "progress.csv").stat().st_mtime_ns for d in stamps}

    # 4. The report: tidy CSV, summary, learning curves, Markdown embedding them; the failed run named.
    # (as if the file registered a comparison: `tsrl experiment` writes it into experiment.json)
    info = json.loads((exp_dir / "experiment.json").read_text())
    info["comparisons"] = [dataclasses.asdict(Comparison(a="fs1", b="baseline"))]
    (exp_dir / "experiment.json").write_text(json.dumps(info))
    paths = write_report(exp_dir)
    assert {p.name for p in paths} == {"results.csv", "summary.csv", "summary.md", "learning_curves.png",
                                       "performance_profile.png", "comparisons.csv"}  # fmt: skip
    with open(exp_dir / "results.csv", newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
    assert tuple(reader.fieldnames) == RESULT_COLUMNS and len(rows) == 3 * len(EXPECTED_ROWS)
    assert {(r["obs"], r["seed"]) for r in rows} == {("fs1", "0"), ("fs1", "1"), ("baseline", "0")}
    with open(exp_dir / "summary.csv", newline="") as f:
        summary = list(csv.DictReader(f))
    assert [(r["obs"], r["seeds"], r["final_env_steps"], r["eval_episodes"]) for r in summary] == [
        ("baseline", "1", "300", "2"),
        ("fs1", "2", "300", "2"),
    ]
    for png in ("learning_curves.png", "performance_profile.png"):
        assert (exp_dir / png).read_bytes()[:4] == b"\x89PNG" and (exp_dir / png).stat().st_size > 10_000
    md = (exp_dir / "summary.md").read_text()
    assert "](learning_curves.png)" in md and "](performance_profile.png)" in md
    assert "| fs1 > baseline | auc | 2/1 |" in md and "p (Holm)" in md
    assert "| fs1 | 2 | 2 |" in md and "| baseline | 1 | 2 |" in md and "stratified bootstrap" in md
    assert f"Failed runs (error.txt in their folders): {baseline_s1.name}" in md

    # 5. `tsrl plot` of run folders: the same statistics as the report.
    result = run_tsrl("plot", str(fs1_s0), str(fs1_s1), str(baseline_s0), "--out", str(tmp_path / "runs.png"))
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "runs.png").read_bytes()[:4] == b"\x89PNG"


def test_demos_are_recorded_once_per_configuration_and_every_run_trains_with_them(tmp_path):
    definition = tmp_path / "tiny-demos.toml"
    definition.write_text(
        TINY.replace("seeds = [0, 1]", "seeds = [0]") + "\n[demos]\nepisodes = 2\nseed = 3\n"
    )
    exp = load_experiment(definition)
    out = io.StringIO()
    outcomes = run_experiment(exp, tmp_path / "results", workers=2, stream=out)
    assert [o.status for o in outcomes] == ["trained", "trained"], [o.error for o in outcomes]
    exp_dir = tmp_path / "results" / "tiny-demos"
    files = sorted((exp_dir / "demos").glob("*.npz"))
    assert [f.name for f in files] == [
        "tsrl-UR5eReach-v0__baseline__taskspace.npz",
        "tsrl-UR5eReach-v0__fs1__taskspace.npz",
    ]
    assert out.getvalue().count("recording 2 demonstrations") == 2
    for cfg in exp.runs(exp_dir.resolve()):
        run_dir = exp_dir / cfg.run_name
        assert cfg.run_name.endswith("__demos") and progress(run_dir) == EXPECTED_ROWS
        record = json.loads((run_dir / "demos.json").read_text())
        demos = load_demos(cfg.agent.demos.path)
        assert record["sha256"] == sha256(cfg.agent.demos.path) and record["episodes"] == 2
        assert demos.meta["obs"] == cfg.obs and demos.meta["recording_seed"] == 3
    # A second call skips the finished runs and records nothing again.
    mtimes = [f.stat().st_mtime_ns for f in files]
    again = io.StringIO()
    assert [o.status for o in run_experiment(exp, tmp_path / "results", stream=again)] == ["skipped"] * 2
    assert "recording" not in again.getvalue() and [f.stat().st_mtime_ns for f in files] == mtimes
    # The arms are the observations alone: demonstrations on in every run are not a variant.
    write_report(exp_dir)
    with open(exp_dir / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert {(r["obs"], r["variant"]) for r in rows} == {("fs1", ""), ("baseline", "")}


def test_experiment_on_a_local_ray_instance(tmp_path):
    pytest.importorskip("ray")
    definition = tmp_path / "tiny-ray.toml"
    # One run: starting a local Ray instance dominates on a 2-core CI machine.
    definition.write_text(
        TINY.replace('["fs1", "baseline"]', '["fs1"]').replace("seeds = [0, 1]", "seeds = [0]")
    )
    result = run_tsrl(
        "experiment",
        str(definition),
        "--ray",
        "local",
        "--workers",
        "1",
        "--out-dir",
        str(tmp_path),
        timeout=600,
    )
    assert result.returncode == 0, result.stderr
    exp_dir = tmp_path / "tiny-ray"
    assert progress(exp_dir / "tsrl-UR5eReach-v0__fs1__taskspace__ddpg__s0") == EXPECTED_ROWS
    assert "1/1 runs: 1 trained" in result.stderr
    assert (exp_dir / "summary.md").is_file() and "wrote" in result.stdout


#: One worker, two runs (the second waits), budgets no test reaches: a Ctrl-C always finds the first run
#: training and the second not started.
LONG = """
obs = ["fs1"]
seeds = [0, 1]
total_timesteps = 1000000
eval_freq = 100
eval_episodes = 2
checkpoint_freq = 100000

[agent]
learning_starts = 100
gradient_steps = 10
batch_size = 64
buffer_size = 2000
"""


def _start_long_experiment(tmp_path: Path, agent: str = "") -> tuple[subprocess.Popen, list[Path]]:
    """`tsrl experiment` of LONG (plus `agent` settings) on one worker, once its first run has written
    its step-0 evaluation (inside training, whose signal handlers are then installed)."""
    definition = tmp_path / "long.toml"
    definition.write_text(LONG + agent)
    run_dirs = [tmp_path / "results" / "long" / c.run_name for c in load_experiment(definition).runs()]
    proc = subprocess.Popen(
        [*TSRL_WITH_CTRL_C, "experiment", str(definition), "--out-dir", str(tmp_path / "results"),
         "--workers", "1", "--no-report"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    deadline = time.monotonic() + 180
    while not ((run_dirs[0] / "progress.csv").is_file() and progress(run_dirs[0])):
        assert proc.poll() is None and time.monotonic() < deadline, "the first run never evaluated"
        time.sleep(0.05)
    return proc, run_dirs


def _communicate(proc: subprocess.Popen) -> str:
    """The process's stderr once it has exited; killed with its workers (its own session) if it has not
    within 180 s, so that a failing test leaves no experiment running."""
    try:
        return proc.communicate(timeout=180)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)  # its own session (start_new_session): it and its workers
            proc.communicate()


def test_a_ctrl_c_asks_the_running_runs_to_checkpoint_and_starts_no_other(tmp_path):
    proc, (first, second) = _start_long_experiment(tmp_path)
    proc.send_signal(signal.SIGINT)
    stderr = _communicate(proc)
    lines = stderr.splitlines()
    assert proc.returncode == 128 + signal.SIGINT, stderr
    assert (
        "stopping: 1 running run(s) save a checkpoint and stop; 1 not started; Ctrl-C again to stop at once"
        in lines
    )
    (done,) = [line for line in lines if line.startswith("[1/2] interrupted")]
    assert first.name in done and "SIGTERM: stopped at" in done and "checkpoint saved" in done
    # A stop is honoured after the env step in progress, so the checkpoint may be at any env step from 0
    # (the signal can arrive in the first step after the step-0 evaluation): that it exists is the point.
    assert latest_checkpoint(first) is not None and not second.exists()
    assert "0 failed, 1 interrupted, 1 not started" in stderr
    assert lines[-1] == "tsrl experiment: interrupted; run it again to resume"


def test_a_second_ctrl_c_ends_the_running_runs_at_once(tmp_path):
    # Updates every 10,000 episodes: after the first Ctrl-C the run's next safe point is far away.
    proc, (first, second) = _start_long_experiment(tmp_path, "train_freq_episodes = 10000\n")
    proc.send_signal(signal.SIGINT)
    while not proc.stderr.readline().startswith("stopping: 1 running run(s)"):
        assert proc.poll() is None
    proc.send_signal(signal.SIGINT)
    stderr = _communicate(proc)
    assert proc.returncode == 128 + signal.SIGINT, stderr
    assert stderr.splitlines()[-1] == "tsrl experiment: interrupted; run it again to resume"
    assert checkpoint_at(first) == 0 and not second.exists()
    check_not_locked(first)  # its worker is gone: the run folder's lock is free


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["experiment", "no-such-experiment"],
            "known: " + ", ".join(sorted(p.stem for p in (REPO / "experiments").glob("*.toml"))),
        ),
        (["experiment", "quick-reach", "--workers", "0"], "--workers must be >= 1"),
        (["experiment", "BAD"], "unknown key 'seed'; accepted: description"),
        (["report", "."], "no run folders in ."),
    ],
)
def test_cli_errors_are_one_line_and_exit_code_2(args, expected, tmp_path):
    if "BAD" in args:
        (tmp_path / "bad.toml").write_text("seed = [0]\n")
        args = [a.replace("BAD", str(tmp_path / "bad.toml")) for a in args]
    result = (
        run_tsrl(*args, "--out-dir", str(tmp_path))
        if args[0] == "experiment"
        else run_tsrl(*args, cwd=tmp_path)
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], result.stderr
    assert not any(tmp_path.glob("*/")), "no results folder for bad input"


FINETUNE = (
    'description = "UR5e reach, then the Panda\'s from scratch and fine-tuned from the UR5e runs."\n'
    'env = ["tsrl/UR5eReach-v0", "tsrl/PandaReach-v0"]\nseeds = [0]\n'
    + TINY[TINY.index("total_timesteps") :].replace("total_timesteps = 300", "total_timesteps = 200")
    + '\n[[finetune]]\nfrom_env = "tsrl/UR5eReach-v0"\nenv = "tsrl/PandaReach-v0"\n'
)


def test_finetune_runs_start_from_their_sources_after_them_and_are_their_own_arm(tmp_path):
    definition = tmp_path / "tiny-finetune.toml"
    definition.write_text(FINETUNE)
    exp = load_experiment(definition)
    exp_dir = (tmp_path / "results" / "tiny-finetune").resolve()
    ur5e, panda, tuned = exp.runs(exp_dir)
    assert tuned.env_id == panda.env_id and tuned.init_from == str(exp_dir / ur5e.run_name)
    assert tuned.run_name == panda.run_name + "__init"
    assert exp.arms() == [
        "tsrl/UR5eReach-v0 / init_from=False",
        "tsrl/PandaReach-v0 / init_from=False",
        "tsrl/PandaReach-v0 / init_from=True",
    ]
    assert exp.arm_runs("tsrl/PandaReach-v0 / init_from=True", exp_dir) == [tuned]
    outcomes = run_experiment(exp, tmp_path / "results", workers=2, stream=io.StringIO())
    assert [o.status for o in outcomes] == ["trained"] * 3, [o.error for o in outcomes]
    record = json.loads((exp_dir / tuned.run_name / "init_from.json").read_text())
    assert str(exp_dir / ur5e.run_name / "checkpoints") in json.dumps(record)
    # The report names the arms as the experiment does.
    write_report(exp_dir)
    with open(exp_dir / "summary.csv", newline="") as f:
        variants = {(r["env"], r["variant"]) for r in csv.DictReader(f)}
    assert variants == {
        ("tsrl/UR5eReach-v0", "init_from=False"),
        ("tsrl/PandaReach-v0", "init_from=False"),
        ("tsrl/PandaReach-v0", "init_from=True"),
    }


def test_a_finetune_whose_source_did_not_finish_fails_naming_it_and_a_stop_starts_none(tmp_path):
    from tsrl.experiments.pool import Progress, _startable
    from tsrl.experiments.runner import RunOutcome

    definition = tmp_path / "tiny-finetune.toml"
    definition.write_text(FINETUNE)
    exp = load_experiment(definition)
    exp_dir = tmp_path / "results" / "tiny-finetune"
    ur5e, _, tuned = exp.runs(exp_dir.resolve())
    outcomes: dict = {}
    display = Progress(exp.runs(exp_dir), exp_dir, io.StringIO())
    assert _startable([tuned], outcomes, display) == []
    assert outcomes[tuned.run_name].status == "failed"
    assert outcomes[tuned.run_name].error == f"its source run {ur5e.run_name} has not finished"
    stopped = {ur5e.run_name: RunOutcome(ur5e.run_name, "interrupted", 100, 1.0)}
    assert _startable([tuned], stopped, display) == []
    assert stopped[tuned.run_name].error == "not started"
    display.close()


def test_a_finetune_from_an_env_outside_the_grid_is_one_error(tmp_path):
    definition = tmp_path / "bad-finetune.toml"
    definition.write_text(
        FINETUNE.replace('from_env = "tsrl/UR5eReach-v0"', 'from_env = "tsrl/UR5ePickPlace-v0"')
    )
    with pytest.raises(
        InvalidConfig,
        match=r"\[finetune\[0\]\] from_env 'tsrl/UR5ePickPlace-v0' is not in the grid; accepted: ",
    ):
        load_experiment(definition)


def test_run_configs_trains_configs_without_a_definition_and_reuses_them(tmp_path):
    from training_helpers import tiny

    from tsrl.experiments.pool import run_configs

    runs = [tiny(seed=0, total=100), tiny(seed=1, total=100)]
    first = run_configs(runs, tmp_path / "suite", workers=2, stream=io.StringIO())
    assert [(o.run_name, o.status, o.env_steps) for o in first] == [
        (c.run_name, "trained", 100) for c in runs
    ]
    assert not (tmp_path / "suite" / "experiment.json").exists()
    again = run_configs(runs, tmp_path / "suite", workers=1, stream=io.StringIO())
    assert [o.status for o in again] == ["skipped", "skipped"]


def test_agents_of_one_experiment_run_into_one_folder_and_are_its_arms(tmp_path):
    definition = tmp_path / "tiny-agents.toml"
    definition.write_text(
        TINY.replace('obs = ["fs1", "baseline"]', 'obs = ["fs1"]')
        + '[[agents]]\n[[agents]]\n[agents.her]\nrelabel = "plain"\n'
        + '[[comparisons]]\na = "agent.her.relabel=feature"\nb = "agent.her.relabel=plain"\n'
    )
    exp = load_experiment(definition)
    outcomes = run_experiment(exp, tmp_path / "results", workers=2, stream=io.StringIO())
    assert [o.status for o in outcomes] == ["trained"] * 4
    write_report(tmp_path / "results" / "tiny-agents")
    with open(tmp_path / "results" / "tiny-agents" / "summary.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["variant"] for r in rows) == ["agent.her.relabel=feature", "agent.her.relabel=plain"]
