"""Training runs on the real reach env: every algorithm writes its run folder; same seed, same run."""

from __future__ import annotations

import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest
from training_helpers import DAMAGE, tiny

from tsrl.agents import HerConfig, load_config, read_progress, resume, train
from tsrl.agents.checkpoint import usable_checkpoint, verify_checkpoint
from tsrl.agents.run_folder import DamagedCheckpoint, checkpoint_dirs, latest_checkpoint, read_state


def buffer_of(run_dir):
    with open(latest_checkpoint(run_dir) / "replay_buffer.pkl", "rb") as f:
        return pickle.load(f)


@pytest.mark.parametrize("algo", ["ddpg", "td3", "sac"])
def test_each_algorithm_trains_and_writes_its_run_folder(algo, tmp_path):
    cfg = tiny(algo)
    run_dir = train(cfg, tmp_path, progress_bar=False)
    assert run_dir.name == f"tsrl-UR5eReach-v0__fs1__taskspace__{algo}__s0"
    assert load_config(run_dir) == cfg
    assert json.loads((run_dir / "config.json").read_text())["agent"]["algo"] == algo
    rows = read_progress(run_dir)
    assert [r["env_steps"] for r in rows] == [0, 100, 200]
    assert [r["episodes"] for r in rows] == [0, 2, 4]
    assert all(0 <= r["eval_success_rate"] <= 1 for r in rows)
    assert all(np.isnan(r["eval_penalised_rate"]) for r in rows)  # reach has no penalty
    assert np.isfinite(rows[-1]["critic_loss"])  # updates happened
    assert any(p.name.startswith("events.out.tfevents") for p in (run_dir / "tb").iterdir())
    checkpoint = latest_checkpoint(run_dir)
    assert checkpoint.name == "step_0000000200"
    assert {p.name for p in checkpoint.iterdir()} >= {"model.zip", "replay_buffer.pkl", "vecnormalize.pkl"}
    assert read_state(checkpoint).episodes == 4
    assert buffer_of(run_dir).pos == 200
    assert (run_dir / "learning_curve.png").stat().st_size > 1000


def test_same_seed_gives_the_same_actions_and_losses(tmp_path):
    a = train(tiny(seed=3), tmp_path / "a", progress_bar=False)
    b = train(tiny(seed=3), tmp_path / "b", progress_bar=False)
    c = train(tiny(seed=4), tmp_path / "c", progress_bar=False)
    buf_a, buf_b, buf_c = buffer_of(a), buffer_of(b), buffer_of(c)
    np.testing.assert_array_equal(buf_a.actions, buf_b.actions)  # random warm-up and policy actions
    np.testing.assert_array_equal(buf_a.observations["observation"], buf_b.observations["observation"])
    losses = [[r["critic_loss"] for r in read_progress(d)] for d in (a, b)]
    assert np.isfinite(losses[0][-1])
    np.testing.assert_array_equal(losses[0], losses[1])
    assert not np.array_equal(buf_a.actions, buf_c.actions)


def test_resume_with_a_larger_budget_continues_counters_buffer_and_normaliser(tmp_path):
    run_dir = train(tiny(total=200), tmp_path / "a", progress_bar=False)
    copy = shutil.copytree(run_dir, tmp_path / "b" / run_dir.name)
    with open(latest_checkpoint(run_dir) / "vecnormalize.pkl", "rb") as f:
        count_before = pickle.load(f).obs_rms["observation"].count
    # The copy's progress.csv as a run folder written before eval_penalised_rate and gradient_steps
    # were recorded.
    progress = copy / "progress.csv"
    lines = progress.read_text().splitlines()
    progress.write_text("".join(line.rsplit(",", 2)[0] + "\n" for line in lines))
    assert "eval_penalised_rate" not in progress.read_text()
    resume(run_dir, total_timesteps=300, progress_bar=False)
    resume(copy, total_timesteps=300, progress_bar=False)
    assert progress.read_text().splitlines()[0].endswith(",eval_penalised_rate,gradient_steps")
    assert [r["env_steps"] for r in read_progress(copy)] == [0, 100, 200, 300]
    # Deterministic given the checkpoint (RNG states restored, the new episode seeded from it).
    np.testing.assert_array_equal(buffer_of(run_dir).actions, buffer_of(copy).actions)
    assert load_config(run_dir).total_timesteps == 300
    rows = read_progress(run_dir)
    assert [r["env_steps"] for r in rows] == [0, 100, 200, 300]
    assert [r["episodes"] for r in rows] == [0, 2, 4, 6]
    assert rows[-1]["wall_time_s"] > rows[-2]["wall_time_s"]
    buffer = buffer_of(run_dir)
    assert buffer.pos == 300 and buffer.buffer_size >= 300  # the buffer came back and grew
    with open(latest_checkpoint(run_dir) / "vecnormalize.pkl", "rb") as f:
        count_after = pickle.load(f).obs_rms["observation"].count
    assert count_before + 100 <= count_after <= count_before + 101  # 100 steps (+ the fresh reset)


def test_plain_her_runs_for_comparison(tmp_path):
    run_dir = train(tiny(her=HerConfig(relabel="plain")), tmp_path, progress_bar=False)
    assert run_dir.name.endswith("__s0__her-plain") and load_config(run_dir).agent.her.relabel == "plain"
    assert [r["env_steps"] for r in read_progress(run_dir)] == [0, 100, 200]


@pytest.fixture(scope="module")
def two_checkpoints(tmp_path_factory) -> Path:
    """A run with checkpoints at 100 and 200 env steps."""
    run_dir = train(tiny(total=200), tmp_path_factory.mktemp("two"), progress_bar=False)
    assert [p.name for p in checkpoint_dirs(run_dir)] == ["step_0000000100", "step_0000000200"]
    return run_dir


@pytest.mark.parametrize("name", DAMAGE)
def test_resume_falls_back_past_a_damaged_file_with_one_warning(name, two_checkpoints, tmp_path, capsys):
    run_dir = shutil.copytree(two_checkpoints, tmp_path / two_checkpoints.name)
    damaged = run_dir / "checkpoints" / "step_0000000200" / name
    DAMAGE[name](damaged)
    capsys.readouterr()
    resume(run_dir, total_timesteps=300, progress_bar=False)
    warnings = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warnings) == 1 and str(damaged) in warnings[0] and "using step_0000000100" in warnings[0]
    rows = read_progress(run_dir)
    assert [(r["env_steps"], r["episodes"]) for r in rows] == [(0, 0), (100, 2), (200, 4), (300, 6)]
    assert [p.name for p in checkpoint_dirs(run_dir)] == ["step_0000000200", "step_0000000300"]
    assert buffer_of(run_dir).pos == 300  # 100 transitions from the checkpoint used, 200 new


def test_a_model_archive_whose_counters_disagree_with_state_json_is_not_used(two_checkpoints, tmp_path):
    run_dir = shutil.copytree(two_checkpoints, tmp_path / two_checkpoints.name)
    older, newer = checkpoint_dirs(run_dir)
    shutil.copy(older / "model.zip", newer / "model.zip")  # a whole archive, of 100 env steps
    with pytest.raises(DamagedCheckpoint, match="disagree with state.json"):
        verify_checkpoint(newer, normalized=True, for_training=True)
    assert usable_checkpoint(run_dir, normalized=True, for_training=True).path == older
