"""The `tsrl` console script: help, the rendering demo, error exit codes."""

import numpy as np
from cli_runner import run_tsrl
from PIL import Image


def test_help_lists_the_commands():
    result = run_tsrl("--help")
    assert result.returncode == 0
    assert "demo" in result.stdout


def test_demo_writes_png_files(tmp_path):
    result = run_tsrl("demo", "--out-dir", str(tmp_path), "--poses", "2")
    assert result.returncode == 0, result.stderr
    pngs = sorted(tmp_path.glob("*.png"))
    assert [p.name for p in pngs] == ["reach_home.png", "reach_random_0.png", "reach_random_1.png"]
    assert np.asarray(Image.open(pngs[0])).std() > 10
    assert str(pngs[0]) in result.stdout


def test_unknown_scene_exits_2_with_one_line_error(tmp_path):
    result = run_tsrl("demo", "--scene", "kitchen", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "unknown scene 'kitchen'" in result.stderr and "reach" in result.stderr
    assert "Traceback" not in result.stderr
