"""`tsrl train --resume / evaluate / render` on run folders with damaged checkpoints.

A damaged file in the newest checkpoint: the previous one is used, with one warning naming the file.
Damaged in every checkpoint: one error line naming the files, exit code 2, the folder as it was.
"""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import pytest
from cli_runner import RUN_NAME, TINY, run_tsrl
from training_helpers import DAMAGE

STEPS = ("step_0000000100", "step_0000000200")


def snapshot(run_dir: Path) -> dict[str, str]:
    """{path: sha256} of every file in the run folder (and its folders)."""
    return {
        str(p.relative_to(run_dir)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "folder"
        for p in sorted(run_dir.rglob("*"))
    }


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A run with checkpoints at 100 and 200 env steps."""
    out = tmp_path_factory.mktemp("runs")
    result = run_tsrl("train", "--out-dir", str(out), *TINY)
    assert result.returncode == 0, result.stderr
    run_dir = out / RUN_NAME
    assert sorted(p.name for p in (run_dir / "checkpoints").iterdir()) == list(STEPS)
    return run_dir


@pytest.fixture
def run_copy(trained, tmp_path) -> Path:
    return shutil.copytree(trained, tmp_path / RUN_NAME)


@pytest.mark.parametrize("name", DAMAGE)
def test_resume_with_every_checkpoint_damaged_is_one_line_exit_2_and_changes_nothing(name, run_copy):
    damaged = [run_copy / "checkpoints" / step / name for step in STEPS]
    for path in damaged:
        DAMAGE[name](path)
    before = snapshot(run_copy)
    result = run_tsrl("train", "--resume", str(run_copy), "--total-timesteps", "300")
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "no usable checkpoint" in lines[0], result.stderr
    assert all(str(path) in lines[0] for path in damaged)
    assert snapshot(run_copy) == before


def test_evaluate_falls_back_past_a_damaged_model_with_one_warning(run_copy):
    damaged = run_copy / "checkpoints" / STEPS[1] / "model.zip"
    DAMAGE["model.zip"](damaged)
    result = run_tsrl("evaluate", str(run_copy), "--episodes", "2")
    assert result.returncode == 0, result.stderr
    assert "(100 env steps)" in result.stdout
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and str(damaged) in warnings[0] and f"using {STEPS[0]}" in warnings[0]


@pytest.mark.parametrize("command", ["evaluate", "render"])
def test_evaluate_and_render_without_a_usable_checkpoint_are_one_line_exit_2(command, run_copy, tmp_path):
    for step in STEPS:
        DAMAGE["vecnormalize.pkl"](run_copy / "checkpoints" / step / "vecnormalize.pkl")
    before = snapshot(run_copy)
    extra = ["--out", str(tmp_path / "v.mp4")] if command == "render" else []
    result = run_tsrl(command, str(run_copy), *extra)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "vecnormalize.pkl" in lines[0] and "no usable checkpoint" in lines[0]
    assert snapshot(run_copy) == before and not (tmp_path / "v.mp4").exists()
