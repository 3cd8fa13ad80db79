"""The `tsrl` console script: help, `tsrl show` (a scene to PNG files) and its old name, error exit codes."""

import numpy as np
from cli_runner import run_tsrl
from PIL import Image


def test_help_lists_the_commands():
    result = run_tsrl("--help")
    assert result.returncode == 0
    assert "show" in result.stdout


def test_show_writes_png_files(tmp_path):
    result = run_tsrl("show", "--out-dir", str(tmp_path), "--poses", "2")
    assert result.returncode == 0, result.stderr
    pngs = sorted(tmp_path.glob("*.png"))
    assert [p.name for p in pngs] == ["reach_home.png", "reach_random_0.png", "reach_random_1.png"]
    assert np.asarray(Image.open(pngs[0])).std() > 10
    assert str(pngs[0]) in result.stdout


ARM = """<mujoco>
  <worldbody>
    <light pos="0 0 3"/>
    <geom type="plane" size="2 2 0.1"/>
    <body name="link" pos="0 0 0.2">
      <joint name="j0" type="hinge" axis="0 0 1" range="-3 3"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      <body pos="0.4 0 0">
        <joint name="j1" type="hinge" axis="0 1 0" range="-2 2"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_show_of_a_model_file_writes_into_out_dir(tmp_path):
    model = tmp_path / "models" / "arm.xml"
    model.parent.mkdir()
    model.write_text(ARM)
    out = tmp_path / "pngs"
    result = run_tsrl("show", "--scene", str(model), "--out-dir", str(out), "--poses", "1")
    assert result.returncode == 0, result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["arm_home.png", "arm_random_0.png"]
    assert [p.name for p in model.parent.iterdir()] == ["arm.xml"]  # nothing beside the model
    assert np.asarray(Image.open(out / "arm_home.png")).std() > 10


def test_unknown_scene_exits_2_with_one_line_error(tmp_path):
    result = run_tsrl("show", "--scene", "kitchen", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "unknown scene 'kitchen'" in result.stderr and "reach" in result.stderr
    assert "Traceback" not in result.stderr


def test_demo_is_a_deprecated_alias_of_show(tmp_path):
    result = run_tsrl("demo", "--out-dir", str(tmp_path), "--poses", "1")
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines() == [
        "tsrl: 'tsrl demo' is deprecated and goes in the next release; use 'tsrl show'"
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["reach_home.png", "reach_random_0.png"]
    assert "Deprecated name of `tsrl show`" in run_tsrl("--help").stdout  # listed as such
