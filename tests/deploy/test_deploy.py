"""End to end: train a tiny reach run, export it, deploy it on the MuJoCo backend, replay its log; the
command line's one-line errors (exit 2) for a bad export, another major version, a mismatched backend."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from training_helpers import tiny

from tsrl.cli import main
from tsrl.deploy.contract import CONTRACT, POLICY
from tsrl.deploy.loop import read_log


@pytest.fixture(scope="module")
def trained_export(tmp_path_factory):
    from tsrl.agents import train

    root = tmp_path_factory.mktemp("e2e")
    run_dir = train(tiny("ddpg", total=200), root / "runs", progress_bar=False)
    assert main(["export", str(run_dir), "--out", str(root / "export")]) == 0
    return root / "export"


def test_train_export_deploy_replay(trained_export, tmp_path, capsys):
    log = tmp_path / "deploy.jsonl"
    assert main(["deploy", str(trained_export), "--episodes", "3", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    assert out.count("episode ") == 3 and "success " in out and "p99" in out
    header, records, episodes = read_log(log)
    assert header["backend"] == "mujoco" and len(episodes) == 3
    cycles = [r for r in records if r["type"] == "cycle"]
    assert len(cycles) == 3 * 50 and all(len(r["servo"]) == 20 for r in cycles)
    first = cycles[0]
    assert len(first["observation"]) == 15 and len(first["action"]) == 3 and len(first["q_target"]) == 6
    assert all(math.isfinite(r["compute_s"]) for r in cycles)
    # The servo commands are continuous across the log's policy steps: each within one tick's speed.
    servo = np.concatenate([np.array(r["servo"]) for r in cycles[:50]])
    assert (np.abs(np.diff(servo, axis=0)) <= np.pi * 0.002 + 1e-12).all()

    video = tmp_path / "replay.gif"
    assert main(["deploy", "--replay", str(log), "--video", str(video), "--video-every", "25"]) == 0
    out = capsys.readouterr().out
    assert "replayed 150 policy steps" in out and "joint target 0 rad" in out and "servo command 0 rad" in out
    assert video.stat().st_size > 0


def test_dry_run_computes_and_logs_but_the_arm_stays(trained_export, tmp_path, capsys):
    log = tmp_path / "dry.jsonl"
    assert main(["deploy", str(trained_export), "--episodes", "1", "--dry-run", "--log", str(log)]) == 0
    assert "dry run: nothing was sent" in capsys.readouterr().out
    _, records, _ = read_log(log)
    cycles = [r for r in records if r["type"] == "cycle"]
    assert len(cycles) == 50 and all(r["q_target"] is not None for r in cycles)
    measured = np.array([r["q"] for r in cycles])
    assert np.abs(measured - measured[0]).max() < 1e-3  # nothing moved the simulated arm


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("tsrl: error: ") and "\n" not in err, err
    return err


def test_an_altered_or_missing_file_is_refused_in_one_line(trained_export, tmp_path, capsys):
    import shutil

    bad = tmp_path / "altered"
    shutil.copytree(trained_export, bad)
    with open(bad / POLICY, "ab") as f:
        f.write(b"\0")
    assert main(["deploy", str(bad), "--episodes", "1", "--log", str(tmp_path / "x.jsonl")]) == 2
    err = one_error_line(capsys)
    assert "policy.onnx: sha256" in err and "differs from the contract's" in err
    assert not (tmp_path / "x.jsonl").exists()  # refused before anything ran
    (bad / POLICY).unlink()
    assert main(["deploy", str(bad)]) == 2
    assert "policy.onnx: missing" in one_error_line(capsys)


def test_a_contract_of_another_major_version_is_refused(trained_export, tmp_path, capsys):
    import shutil

    bad = tmp_path / "v9"
    shutil.copytree(trained_export, bad)
    contract = json.loads((bad / CONTRACT).read_text())
    contract["tsrl_version"] = "9.0.0"
    (bad / CONTRACT).write_text(json.dumps(contract))
    assert main(["deploy", str(bad)]) == 2
    err = one_error_line(capsys)
    assert "tsrl_version 9.0.0 (major 9)" in err and "export the run again" in err


def test_bad_deploy_options_are_one_line(trained_export, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default log, deploy.jsonl, would go here: nothing may be written
    assert main(["deploy", str(trained_export), "--backend", "ur"]) == 2
    assert "--backend ur needs --address" in one_error_line(capsys)
    assert main(["deploy", str(trained_export), "--goal", "0.1,x"]) == 2
    assert "--goal must be comma-separated numbers" in one_error_line(capsys)
    assert main(["deploy", str(trained_export), "--goal", "0.1,0.2"]) == 2
    assert "goal has 2 values" in one_error_line(capsys)
    assert main(["deploy"]) == 2
    assert "needs EXPORT_DIR" in one_error_line(capsys)
    assert main(["deploy", str(trained_export), "--backend", "ur", "--address", "192.0.2.1"]) == 2
    assert "pip install 'tsrl[ur]'" in one_error_line(capsys)  # ur-rtde is not installed here
    assert list(tmp_path.iterdir()) == []  # no log of a deployment that never connected


def test_export_of_a_folder_that_is_not_a_run_is_one_line(tmp_path, capsys):
    assert main(["export", str(tmp_path), "--out", str(tmp_path / "x")]) == 2
    assert "is not a run folder" in one_error_line(capsys)


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT"])
def test_a_signal_stops_the_deployment_after_the_servo_tick_in_progress(
    trained_export, tmp_path, capsys, monkeypatch, sig
):
    """SIGTERM or SIGINT in the middle of an episode: no further command is sent, the backend is
    closed (which stops the arm), the log ends with the episode stopped by it, exit 128 + the signal."""
    import os
    import signal

    from tsrl.deploy.backends import MujocoBackend

    send, close = MujocoBackend.send, MujocoBackend.close
    sent, closed = [], []

    def sending(self, *args, **kwargs):
        sent.append(1)
        if len(sent) == 30:  # the second policy step's tenth servo tick (20 ticks a step)
            os.kill(os.getpid(), getattr(signal, sig))
        return send(self, *args, **kwargs)

    def closing(self):
        closed.append(len(sent))
        return close(self)

    monkeypatch.setattr(MujocoBackend, "send", sending)
    monkeypatch.setattr(MujocoBackend, "close", closing)
    log = tmp_path / "deploy.jsonl"
    assert main(["deploy", str(trained_export), "--episodes", "3", "--log", str(log)]) == 128 + getattr(
        signal, sig
    )
    assert len(sent) == 30 and closed == [30]  # not one command after the signal's tick
    out = capsys.readouterr().out
    assert f"stopped in episode 0: {sig}: stopped on the operator's signal" in out
    _, records, episodes = read_log(log)
    assert len(episodes) == 1 and episodes[0]["stopped"].startswith(sig)
    assert [len(r["servo"]) for r in records if r["type"] == "cycle"] == [20, 10]
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handlers were put back
    video = tmp_path / "replay.mp4"  # the stopped log replays to the same commands
    assert main(["deploy", "--replay", str(log), "--video", str(video), "--video-every", "25"]) == 0
