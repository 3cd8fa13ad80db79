"""`tsrl train / evaluate / render` as subprocesses: run folders, kill-and-resume, bad input."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_runner import RUN_NAME, TINY, TSRL_WITH_CTRL_C, run_tsrl


def spawn(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [*TSRL_WITH_CTRL_C, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def steps_column(run_dir: Path) -> list[tuple[int, int]]:
    with open(run_dir / "progress.csv", newline="") as f:
        return [(int(r["env_steps"]), int(r["episodes"])) for r in csv.DictReader(f)]


def wait_for(predicate, proc: subprocess.Popen, timeout: float = 90) -> None:
    end = time.monotonic() + timeout
    while not predicate():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "timed out"
        time.sleep(0.05)


def checkpoint_steps(run_dir: Path) -> list[int]:
    root = run_dir / "checkpoints"
    return sorted(int(p.name[5:]) for p in root.glob("step_*")) if root.is_dir() else []


@pytest.fixture(scope="module")
def trained_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("runs")
    result = run_tsrl(
        "train", "--env", "tsrl/UR5eReach-v0", "--obs", "fs1", "--action", "taskspace", "--algo", "ddpg",
        "--seed", "0", "--out-dir", str(out), *TINY,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return out / RUN_NAME.replace("__baseline__", "__fs1__")  # fs1 given, not the reach's own


def test_train_writes_a_self_describing_run_folder(trained_run):
    config = json.loads((trained_run / "config.json").read_text())
    assert (
        config["env_id"] == "tsrl/UR5eReach-v0"
        and config["obs"] == "fs1"
        and config["agent"]["algo"] == "ddpg"
    )
    assert config["total_timesteps"] == 200 and config["agent"]["her"]["relabel"] == "feature"
    assert steps_column(trained_run) == [(0, 0), (100, 2), (200, 4)]
    with open(trained_run / "progress.csv", newline="") as f:
        assert {"env_steps", "episodes", "wall_time_s", "eval_success_rate"} <= set(
            csv.DictReader(f).fieldnames
        )
    assert list((trained_run / "tb").glob("events.out.tfevents*"))
    assert checkpoint_steps(trained_run) == [100, 200]  # the last two
    assert (trained_run / "learning_curve.png").is_file()


def test_evaluate_prints_success_rate_and_final_distance(trained_run):
    result = run_tsrl("evaluate", str(trained_run), "--episodes", "3")
    assert result.returncode == 0, result.stderr
    assert "success rate" in result.stdout and "mean final distance" in result.stdout
    assert "3 episodes" in result.stdout


def test_render_writes_a_video(trained_run, tmp_path):
    result = run_tsrl(
        "render",
        str(trained_run),
        "--out",
        str(tmp_path / "policy.mp4"),
        "--episodes",
        "1",
        "--size",
        "160",
        "120",
    )
    assert result.returncode == 0, result.stderr
    written = Path(result.stdout.split("wrote ")[-1].strip())
    assert written.parent == tmp_path and written.suffix in (".mp4", ".gif")
    assert written.stat().st_size > 2_000
    if written.suffix == ".mp4":
        import imageio_ffmpeg

        reader = imageio_ffmpeg.read_frames(str(written))
        meta = next(reader)
        assert tuple(meta["size"]) == (160, 120)
        assert sum(1 for _ in reader) == 51  # reset + 50 steps


def test_a_live_run_refuses_a_second_trainer_then_sigkill_and_resume_continue_counters(tmp_path):
    # A budget the trainer cannot reach during the test (a small buffer: checkpoints stay small).
    proc = spawn(
        "train", "--out-dir", str(tmp_path), *TINY, "--total-timesteps", "1000000", "--buffer-size", "2000"
    )
    run_dir = tmp_path / RUN_NAME
    wait_for(lambda: any(s >= 200 for s in checkpoint_steps(run_dir)), proc)
    proc.send_signal(signal.SIGSTOP)  # alive and holding the lock, but frozen wherever it had got to
    refused = run_tsrl("train", "--resume", str(run_dir))
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1, refused.stderr
    assert f"being trained by process {proc.pid}" in refused.stderr
    proc.send_signal(signal.SIGKILL)
    proc.communicate()
    assert (run_dir / "train.lock").read_text().strip() == str(proc.pid)  # left behind by the killed one
    # The budget comes from the folder: 300 env steps past the newest checkpoint, however far it got.
    killed_at = max(checkpoint_steps(run_dir))
    assert killed_at >= 200 and killed_at % 100 == 0
    budget = killed_at + 300
    result = run_tsrl("train", "--resume", str(run_dir), "--total-timesteps", str(budget))
    assert result.returncode == 0, result.stderr
    assert not (run_dir / "train.lock").exists()
    assert steps_column(run_dir) == [(s, s // 50) for s in range(0, budget + 1, 100)]  # each row once
    assert checkpoint_steps(run_dir) == [budget - 100, budget]
    state = json.loads((run_dir / "checkpoints" / f"step_{budget:010d}" / "state.json").read_text())
    assert (state["env_steps"], state["episodes"]) == (budget, budget // 50)
    assert json.loads((run_dir / "config.json").read_text())["total_timesteps"] == budget


def test_sigterm_saves_a_checkpoint_then_resume_finishes(tmp_path):
    proc = spawn(  # a budget it cannot finish before the signal, and no periodic checkpoint
        "train", "--out-dir", str(tmp_path), *TINY, "--total-timesteps", "1000000", "--buffer-size", "2000",
        "--checkpoint-freq", "1000000",
    )  # fmt: skip
    run_dir = tmp_path / RUN_NAME
    wait_for(lambda: (run_dir / "progress.csv").is_file() and len(steps_column(run_dir)) >= 2, proc)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM, stderr
    assert "checkpoint saved" in stderr and "--resume" in stderr and "Traceback" not in stderr
    (stopped_at,) = checkpoint_steps(run_dir)  # the signal's checkpoint, not a periodic one
    assert stopped_at >= 100  # after the env step in progress: possibly inside an episode
    result = run_tsrl("train", "--resume", str(run_dir), "--total-timesteps", str(stopped_at + 100))
    assert result.returncode == 0, result.stderr
    steps = [s for s, _ in steps_column(run_dir)]
    assert steps == sorted(set(steps)) and steps[-1] >= stopped_at + 100  # one row per evaluation, to the end
    assert [s for s in steps if s <= stopped_at] == list(range(0, stopped_at // 100 * 100 + 1, 100))  # kept


def learning_columns(run_dir: Path) -> list[tuple[str, ...]]:
    """progress.csv without its wall-clock columns: what the agent learned, row by row."""
    with open(run_dir / "progress.csv", newline="") as f:
        return [tuple(v for k, v in r.items() if not k.endswith("time_s")) for r in csv.DictReader(f)]


@pytest.mark.parametrize("off", [["--demos-bc-weight", "0"], ["--demos-batch-share", "0"]])
def test_demonstrations_off_train_the_run_without_them(off, trained_run, tmp_path):
    demos = tmp_path / "reach.npz"
    recorded = run_tsrl(
        "demos",
        "record",
        "--env",
        "tsrl/UR5eReach-v0",
        "--obs",
        "fs1",
        "--episodes",
        "2",
        "--out",
        str(demos),
    )
    assert recorded.returncode == 0, recorded.stderr
    out = tmp_path / "runs"
    result = run_tsrl("train", "--out-dir", str(out), "--obs", "fs1", *TINY, "--demos", str(demos), *off)
    assert result.returncode == 0, result.stderr
    (run_dir,) = out.iterdir()
    assert run_dir.name == trained_run.name  # not ...__demos
    assert not (run_dir / "demos.json").exists()
    assert json.loads((run_dir / "config.json").read_text())["agent"]["demos"]["path"] == str(demos)
    assert learning_columns(run_dir) == learning_columns(trained_run)  # the run without demonstrations


#: `python -c` running the real `tsrl` as its console script does (argv after the code) with one pause
#: in its start-up: at the first `import torch` (Train.run loads torch once the input is valid) it prints
#: "importing torch" and waits for a line on stdin, so a SIGINT sent after that line arrives during
#: start-up, every time.
PAUSE_AT_TORCH_IMPORT = """
import signal
import sys

signal.signal(signal.SIGINT, signal.default_int_handler)  # as TSRL_WITH_CTRL_C: not ignored

def pause(event, args):
    if event == "import" and args[0] == "torch" and not paused:
        paused.append(True)
        print("importing torch", flush=True)
        sys.stdin.readline()

paused = []
sys.addaudithook(pause)
from tsrl.cli import main
sys.exit(main())
"""


def test_ctrl_c_during_start_up_is_one_line_and_exit_130(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-c", PAUSE_AT_TORCH_IMPORT, "train", "--out-dir", str(tmp_path), *TINY],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert proc.stdout.readline() == "importing torch\n"
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGINT, stderr
    assert stderr.splitlines() == ["tsrl: interrupted"]
    assert not any(tmp_path.iterdir())


#: tsrl with its checkpoint saving held until stdin has a line: a save that takes long (a large
#: replay buffer on a slow disk), so that the first Ctrl-C cannot be honoured before a second one.
HOLD_AT_CHECKPOINT = """
import runpy, signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # as TSRL_WITH_CTRL_C: not ignored
import tsrl.agents.training as training

save = training.save_checkpoint

def held(*args, **kwargs):
    print("checkpointing", flush=True)
    sys.stdin.readline()
    return save(*args, **kwargs)

training.save_checkpoint = held
sys.argv[0] = "tsrl"
runpy.run_module("tsrl.cli", run_name="__main__", alter_sys=True)
"""


def test_a_second_ctrl_c_stops_at_once_in_one_line_and_exit_130(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-c", HOLD_AT_CHECKPOINT, "train", "--out-dir", str(tmp_path), *TINY,
         "--total-timesteps", "1000000", "--buffer-size", "2000"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    run_dir = tmp_path / RUN_NAME
    while proc.stdout.readline() != "checkpointing\n":  # a checkpoint is being saved, and held
        assert proc.poll() is None
    proc.send_signal(signal.SIGINT)  # noted: the run would stop once the save is done
    while "SIGINT: stopping after the step in progress" not in proc.stderr.readline():
        assert proc.poll() is None
    proc.send_signal(signal.SIGINT)  # a second one: at once
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGINT, stderr
    expected = (
        "tsrl train: interrupted at once, without saving a checkpoint; "
        f"continue with: tsrl train --resume {run_dir}"
    )
    assert stderr.splitlines() == [expected]
    assert checkpoint_steps(run_dir) == [] and not (run_dir / "train.lock").exists()


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["train", "--env", "tsrl/Kitchen-v0"], "tsrl/UR5eReach-v0"),
        (["train", "--obs", "fs9", "--total-timesteps", "100"], "fs1"),
        (["train", "--algo", "ppo"], "ddpg"),
        (["train", "--action", "fly"], "taskspace"),
        (["train", "--total-timesteps", "0"], "total_timesteps must be > 0"),
        (["train", "--her", "magic"], "feature"),
        (["train", "--resume", "."], "not a run folder"),
        (["evaluate", "no/such/run"], "not a run folder"),
        (["render", "."], "not a run folder"),
        (["train", "--seed", "abc"], "--seed: invalid literal for int() with base 10: 'abc'"),
        (["train", "--net-arch", "64", "x"], "--net-arch"),
        (["train", "--no-such-option", "1"], "unrecognized arguments: --no-such-option 1"),
        (["fly"], "unrecognized arguments: fly"),
        ([], "missing command; accepted: train, evaluate, render, plot, show, demos, experiment, report"),
        (["evaluate"], "missing RUN_DIR"),
        (["evaluate", ".", "--episodes", "0"], "--episodes must be >= 1; got 0"),
        (["render", ".", "--size", "8", "8"], "--size must be at least 16 16; got 8 8"),
        (["plot"], "at least one RUN_DIR"),
        (["show", "--poses", "-1"], "--poses must be >= 0; got -1"),
    ],
)
def test_bad_input_is_one_line_and_exit_code_2(args, expected, tmp_path):
    result = (
        run_tsrl(*args, "--out-dir", str(tmp_path))
        if args[:1] == ["train"] and "--resume" not in args
        else run_tsrl(*args)
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], result.stderr
    assert "Traceback" not in result.stderr
    assert not any(tmp_path.iterdir())  # no half-made run folder


def test_an_environment_outside_tsrl_gets_one_answer(tmp_path):
    plain = run_tsrl("train", "--env", "CartPole-v1", "--out-dir", str(tmp_path))
    native = run_tsrl(  # what the first answer used to suggest
        "train", "--env", "CartPole-v1", "--obs", "native", "--action", "native", "--out-dir", str(tmp_path)
    )
    assert plain.returncode == native.returncode == 2
    assert plain.stderr == native.stderr and len(plain.stderr.strip().splitlines()) == 1, plain.stderr
    line = plain.stderr.strip()
    assert line.startswith("tsrl: error: unknown environment 'CartPole-v1'")
    assert "tsrl/UR5eReach-v0" in line and "task file" in line  # what is accepted
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--seed", "3"], "only --total-timesteps may be given with it, got --seed"),
        (["--her-strategy", "final", "--algo", "td3"], "got --algo, --her-strategy"),
        (["--demos-batch-share", "0.2"], "got --demos-batch-share"),  # flags as tyro defines them
        (["--demos", "demos.npz", "--no-demos-q-filter"], "got --demos, --no-demos-q-filter"),
        (["--demos-path=demos.npz"], "got --demos-path"),  # the alias the user typed
        (["--env", "tsrl/PandaReach-v0"], "got --env"),
        (["--total-timesteps", "100"], "--total-timesteps 100 is below the 200 env steps already done"),
    ],
)
def test_resume_takes_only_a_new_budget(args, expected, trained_run):
    before = {p: p.stat().st_mtime_ns for p in trained_run.rglob("*")}
    result = run_tsrl("train", "--resume", str(trained_run), *args)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], result.stderr
    assert before == {p: p.stat().st_mtime_ns for p in trained_run.rglob("*")}


def test_help_lists_the_training_commands():
    result = run_tsrl("--help")
    assert result.returncode == 0
    for command in ("train", "evaluate", "render", "show"):
        assert command in result.stdout
    assert "--her-strategy" in run_tsrl("train", "--help").stdout
    assert os.environ.get("MUJOCO_GL", "egl")
