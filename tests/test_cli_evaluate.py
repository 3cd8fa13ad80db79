"""`tsrl evaluate --env/--task/--perturb`, `tsrl train --init-from` and an experiment's evaluation-only
arms, as a user runs them: results on success, one line and exit 2 (nothing written) on bad input."""

from __future__ import annotations

import csv

import pytest
from cli_runner import RUN_NAME, TINY, run_tsrl

PANDA = "tsrl/PandaReach-v0"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs")
    done = run_tsrl("train", *TINY, "--out-dir", str(out))
    assert done.returncode == 0, done.stderr
    return out / RUN_NAME


def _refused(done, *expected: str) -> str:
    assert done.returncode == 2, done.stderr
    # Gymnasium's warning that a v0 id has a v1 may come first: it is not tsrl's line.
    lines = [line for line in done.stderr.strip().splitlines() if "DeprecationWarning" not in line]
    lines = [line for line in lines if line.strip() != "logger.deprecation("]
    assert len(lines) == 1 and lines[0].startswith("tsrl: error: "), done.stderr
    for text in expected:
        assert text in lines[0]
    return lines[0]


def test_a_policy_is_evaluated_on_the_other_arm(run):
    done = run_tsrl("evaluate", str(run), "--env", PANDA, "--episodes", "2")
    assert done.returncode == 0, done.stderr
    assert f"on {PANDA}: success rate" in done.stdout and "(0/2 episodes)" in done.stdout


def test_another_layout_is_one_line(run):
    _refused(
        run_tsrl("evaluate", str(run), "--env", "tsrl/UR5ePickPlace-v0"),
        "tsrl/UR5ePickPlace-v0 does not match the layout of tsrl/UR5eReach-v0: goal row 0",
    )


def test_a_perturbation_sweep_writes_its_table_and_plot(run):
    done = run_tsrl("evaluate", str(run), "--perturb", "servo_gain=0.5,2", "--episodes", "2")
    assert done.returncode == 0, done.stderr
    table = run / "perturb__servo_gain.csv"
    assert table.is_file() and table.with_suffix(".png").is_file()
    with open(table) as f:
        rows = list(csv.DictReader(f))
    assert [(r["perturb_key"], float(r["perturb_value"])) for r in rows] == [
        ("servo_gain", 0.5),
        ("servo_gain", 2.0),
    ]
    assert f"| {RUN_NAME}@0.5 |" in done.stdout and f"wrote {table}" in done.stdout


@pytest.mark.parametrize(
    ("perturb", "expected"),
    [
        ("latency=1,2", "unknown perturbation key 'latency'; accepted: object_mass"),
        ("observation_noise=0,-0.005", "observation_noise = -0.005; accepted: values >= 0"),
        ("action_latency=0,50", "randomize.action_latency = [50, 50]; accepted: 0 to 49"),
        ("control_jitter=0.9", "randomize.control_jitter = 0.9; accepted: 0 to 0.5"),
    ],
)
def test_bad_perturbations_are_one_line_and_write_nothing(run, perturb, expected):
    before = sorted(p.name for p in run.iterdir())
    _refused(run_tsrl("evaluate", str(run), "--perturb", perturb), expected)
    assert sorted(p.name for p in run.iterdir()) == before


def test_init_from_fine_tunes_on_the_other_arm(run, tmp_path):
    done = run_tsrl("train", *TINY, "--env", PANDA, "--init-from", str(run), "--out-dir", str(tmp_path))
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "tsrl-PandaReach-v0__baseline__taskspace__ddpg__s0__init" / "init_from.json").is_file()


@pytest.mark.parametrize(
    ("options", "expected"),
    [
        (["--algo", "sac"], "algo is 'ddpg' there, 'sac' here"),
        (["--net-arch", "64", "64"], "net_arch is 256 256 there, 64 64 here"),
        (["--obs", "fs2"], "observation baseline, action taskspace"),
    ],
)
def test_init_from_an_incompatible_run_is_one_line_and_writes_nothing(run, tmp_path, options, expected):
    out = tmp_path / "out"
    _refused(run_tsrl("train", *TINY, *options, "--init-from", str(run), "--out-dir", str(out)), expected)
    assert not out.exists()


EXPERIMENT = """\
description = "train on UR5e, evaluate on the Panda"
env = ["tsrl/UR5eReach-v0"]
obs = ["fs1"]
seeds = [0, 1]
total_timesteps = 200
eval_freq = 100
eval_episodes = 2
checkpoint_freq = 100

[agent]
learning_starts = 100
gradient_steps = 10
batch_size = 64

[[evaluate]]
name = "on-ur5e"
arm = "fs1"
env = "tsrl/UR5eReach-v0"
episodes = 3

[[evaluate]]
name = "on-panda"
arm = "fs1"
env = "tsrl/PandaReach-v0"
episodes = 3

[[evaluate]]
name = "noise"
arm = "fs1"
env = "tsrl/UR5eReach-v0"
episodes = 3
perturb = { key = "observation_noise", values = [0, 0.01] }

[[comparisons]]
a = "on-panda"
b = "on-ur5e"
metric = "success"
direction = "less"
"""


def test_an_experiment_evaluates_its_evaluation_only_arms_and_reports_them(tmp_path):
    definition = tmp_path / "cross.toml"
    definition.write_text(EXPERIMENT)
    done = run_tsrl("experiment", str(definition), "--workers", "1", "--out-dir", str(tmp_path), timeout=300)
    assert done.returncode == 0, done.stderr
    exp_dir = tmp_path / "cross"
    with open(exp_dir / "evaluations.csv") as f:
        rows = list(csv.DictReader(f))
    labels = sorted((r["label"], int(r["seed"])) for r in rows)
    expected = ["noise@0", "noise@0.01", "on-panda", "on-ur5e"]
    assert labels == [(label, seed) for label in expected for seed in (0, 1)]
    by = {(r["label"], r["seed"]): r for r in rows}
    for seed in ("0", "1"):  # the same episodes: the nominal sweep point is the own-arm evaluation
        assert by["noise@0", seed]["final_distance_m"] == by["on-ur5e", seed]["final_distance_m"]
        assert by["on-panda", seed]["task"] == PANDA and by["on-panda", seed]["episodes"] == "3"
    summary = (exp_dir / "summary.md").read_text()
    assert (
        "## Evaluation-only arms" in summary and "| on-panda | fs1 | tsrl/PandaReach-v0 | 2 | 3 |" in summary
    )
    assert "on-panda < on-ur5e | success | 2/2" in summary
    assert (exp_dir / "robustness__observation_noise.png").is_file()
    again = run_tsrl("experiment", str(definition), "--workers", "1", "--out-dir", str(tmp_path))
    assert again.returncode == 0 and "evaluated" not in again.stderr  # kept, not recomputed
    (exp_dir / "evaluations.csv").unlink()  # the same evaluations on two processes: the same rows
    parallel = run_tsrl(
        "experiment", str(definition), "--workers", "2", "--out-dir", str(tmp_path), timeout=300
    )
    assert parallel.returncode == 0 and parallel.stderr.count("evaluated ") == 6, parallel.stderr
    with open(exp_dir / "evaluations.csv") as f:
        rows_2 = list(csv.DictReader(f))
    assert [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows_2] == [
        {k: v for k, v in r.items() if k != "wall_time_s"} for r in rows
    ]


def test_an_evaluation_arm_of_another_layout_is_refused_when_the_file_loads(tmp_path):
    definition = tmp_path / "bad.toml"
    definition.write_text(EXPERIMENT.replace('env = "tsrl/PandaReach-v0"', 'env = "tsrl/PandaPickPlace-v0"'))
    _refused(
        run_tsrl("experiment", str(definition), "--out-dir", str(tmp_path)),
        "[evaluate[1]]",
        "tsrl/PandaPickPlace-v0 does not match the layout of tsrl/UR5eReach-v0",
    )
    assert not (tmp_path / "bad").exists()
