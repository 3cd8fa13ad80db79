"""`tsrl robot check FILE`: the doctor lists the arm, checks the settling target and a reach box, writes
pictures; exit 0 when everything holds, 2 with one line per problem."""

from __future__ import annotations

import importlib.util

import mujoco
import numpy as np
import pytest
from cli_runner import REPO, run_tsrl
from PIL import Image

from tsrl.kinematics import forward_kinematics
from tsrl.robot_check import box_points, check_robot, reach_box
from tsrl.robot_model import load_robot_model
from tsrl.robots import HOME_KEY, load_robot

ARM_XML = """<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002"/>
  <worldbody>
    <light pos="0 0 3"/>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <camera name="top" pos="0.3 0 2.5"/>
    <body name="base" pos="0 0 0.1">
      <joint name="yaw" axis="0 0 1" range="-3 3" damping="2" armature="0.1"/>
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="upper" pos="0 0 0.05">
        <joint name="shoulder" axis="0 1 0" range="-2 2" damping="2" armature="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
        <body name="fore" pos="0.4 0 0">
          <joint name="elbow" axis="0 1 0" range="-2.5 2.5" damping="2" armature="0.1"/>
          <geom type="capsule" fromto="0 0 0 0.35 0 0" size="0.025" mass="0.5"/>
          <site name="tool" pos="0.35 0 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
ROBOT_TOML = """name = "arm3"
model = "arm.xml"
joints = ["yaw", "shoulder", "elbow"]
tcp = "tool"
home = [0.0, -0.5, 1.0]
"""
FETCH = REPO / "examples" / "robots" / "fetch.toml"
needs_gymnasium_robotics = pytest.mark.skipif(
    importlib.util.find_spec("gymnasium_robotics") is None,
    reason="Gymnasium-Robotics is not installed (pip install gymnasium-robotics==1.4.2; the dev extra has it)",
)


@pytest.fixture
def robot_file(tmp_path):
    (tmp_path / "arm.xml").write_text(ARM_XML)
    path = tmp_path / "arm.toml"
    path.write_text(ROBOT_TOML)
    return path


def test_the_built_in_ur5e_passes():
    result = run_tsrl("robot", "check", "ur5e", "--no-images")
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "robot 'ur5e': model ur5e" in out and "servos: the model's own" in out
    assert "  elbow          hinge  [-3.142, 3.142] rad" in out
    assert "settling: meets the settling target" in out
    assert "9/9 points (corners, centre) reached by the IK from home" in out
    assert out.rstrip().endswith("ok: every check holds") and result.stderr == ""


def test_an_added_servo_arm_passes_and_its_pictures_show_the_arm_at_the_corners(robot_file, tmp_path):
    out_dir = tmp_path / "pictures"
    report = check_robot(str(robot_file), box_half_extent=(0.08, 0.08, 0.08), out_dir=out_dir)
    assert report.problems == ()
    text = "\n".join(report.lines)
    assert (
        "servos: added by tsrl, critically damped at 15 Hz" in text and "gravity compensation added" in text
    )
    assert "  yaw:servo       m = " in text
    assert "tcp: tool (site), at home" in text and "base: world" in text
    assert [p.name for p in report.images] == ["arm3_home.png"] + [f"arm3_corner_{i}.png" for i in range(8)]
    images = [np.asarray(Image.open(p)) for p in report.images]
    assert all(im.std() > 10 for im in images)
    assert all(np.any(images[0] != im, axis=-1).mean() > 0.002 for im in images[1:])  # the arm moved


def test_the_box_corners_are_where_the_ik_puts_the_tcp(robot_file):
    robot = load_robot(robot_file)
    model, _ = load_robot_model(robot, str(robot_file))
    home = robot.home_q(model)
    forward_kinematics(model, (data := mujoco.MjData(model)), home, robot.joints)
    points = box_points(data.site("tool").xpos.copy(), np.array([0.05, 0.08, 0.06]))
    assert points.shape == (9, 3)
    np.testing.assert_allclose(points[0] - points[8], [-0.05, -0.08, -0.06])
    box = reach_box(model, robot, home, model.key(HOME_KEY).id, points)
    assert box.converged.all()
    for q, point in zip(box.q, points, strict=True):  # an independent forward-kinematics pass
        forward_kinematics(model, data, q, robot.joints)
        np.testing.assert_allclose(data.site("tool").xpos, point, atol=2e-4)


def test_an_unreachable_box_and_soft_servos_are_one_line_each_and_exit_2(robot_file):
    robot_file.write_text(ROBOT_TOML + "servo_bandwidth = 2.0\n")
    result = run_tsrl("robot", "check", str(robot_file), "--no-images", "--box-center", "3", "0", "0.3")
    assert result.returncode == 2
    problems = result.stderr.strip().splitlines()
    assert len(problems) == 10  # the settling target and 9 points
    assert problems[0].startswith(f"tsrl robot check: {robot_file}: settling: misses the settling target")
    assert all(p.startswith(f"tsrl robot check: {robot_file}: reach box: [") for p in problems[1:])
    assert "not reached by the IK from home (residual" in problems[1]
    assert "ok: every check holds" not in result.stdout


def test_a_bad_robot_file_is_one_line_naming_the_file_and_the_key(robot_file):
    robot_file.write_text(ROBOT_TOML.replace('tcp = "tool"', 'tcp = "gripper"'))
    result = run_tsrl("robot", "check", str(robot_file))
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.startswith(
        f"tsrl: error: {robot_file}: tcp: unknown frame 'gripper'; the model's frames:"
    )
    assert len(result.stderr.strip().splitlines()) == 1


def test_a_camera_of_the_model_takes_the_pictures(robot_file, tmp_path):
    top = check_robot(str(robot_file), out_dir=tmp_path / "top", camera="top").images[0]
    free = check_robot(str(robot_file), out_dir=tmp_path / "free").images[0]
    assert np.any(np.asarray(Image.open(top)) != np.asarray(Image.open(free)), axis=-1).mean() > 0.2
    result = run_tsrl("robot", "check", str(robot_file), "--camera", "side", "--out-dir", str(tmp_path))
    assert result.returncode == 2
    assert "unknown camera 'side'; the model's cameras: top" in result.stderr


@needs_gymnasium_robotics
def test_the_fetch_arm_as_gymnasium_robotics_ships_it_passes(tmp_path):
    result = run_tsrl("robot", "check", str(FETCH), "--out-dir", str(tmp_path))
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "servos: added by tsrl, critically damped at 15 Hz" in out
    assert "dropped: weld (unnamed) between robot0:mocap and robot0:gripper_link" in out
    assert "notice: " in out and "robot0:upperarm_roll_joint" in out
    assert "settling: meets the settling target" in out and "9/9 points" in out
    assert len(list(tmp_path.glob("fetch_*.png"))) == 9


def test_a_robot_without_home_at_a_singular_zero_pose_is_told_to_give_home(robot_file):
    robot_file.write_text(ROBOT_TOML.replace("home = [0.0, -0.5, 1.0]\n", ""))  # zero pose: arm straight
    result = run_tsrl("robot", "check", str(robot_file), "--no-images")
    assert result.returncode == 2 and result.stdout == ""
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith(
        f"tsrl: error: {robot_file}: no `home`, so the arm starts at the model's zero pose"
    )
    assert "cannot move the TCP 5 cm along +x, +y, +z, -x, -y, -z" in line and "give `home`" in line
    robot_file.write_text(ROBOT_TOML.replace("home = [0.0, -0.5, 1.0]", "home = [0.0, 0.0, 0.0]"))
    result = run_tsrl("robot", "check", str(robot_file), "--no-images")  # the same pose, named: no hint
    assert result.returncode == 2 and "no `home`" not in result.stderr
