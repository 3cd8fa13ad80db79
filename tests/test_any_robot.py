"""The robot-agnostic core on a model written here: a redundant 4-joint planar arm (kinematics, task
maps with finite-difference Jacobians, IK with its null-space posture term and joint limits, Robot)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.exceptions import InvalidConfig, UnknownName
from tsrl.ik import DlsSolver, IKOptions
from tsrl.kinematics import (
    arm_dof_indices,
    arm_qpos_indices,
    controlled_joints,
    forward_kinematics,
    joint_limits,
    random_configurations,
)
from tsrl.robot_model import prepare_spec
from tsrl.robots import HOME_KEY, Robot
from tsrl.servos import servo_name
from tsrl.settling import settle
from tsrl.taskmaps import parse_spec

#: Four hinges about y, links along z: the tool moves in the x-z plane (2 task dimensions, 4 joints).
#: A loose ball with a free joint comes first, so the arm's qpos and dofs do not start at 0.
PLANAR_ARM = """
<mujoco model="planar4">
  <compiler angle="radian" autolimits="true"/>
  <worldbody>
    <geom name="ground" type="box" size="1 1 0.05" pos="0 0 -0.05"/>
    <body name="ball" pos="0.6 0.6 0.2">
      <freejoint name="ball"/>
      <geom name="ball" type="sphere" size="0.03"/>
    </body>
    <body name="link1" pos="0 0 0.05">
      <joint name="j1" axis="0 1 0" range="-2.5 2.5"/>
      <geom name="link1" type="capsule" fromto="0 0 0 0 0 0.3" size="0.03"/>
      <body name="link2" pos="0 0 0.3">
        <joint name="j2" axis="0 1 0" range="-2.5 2.5"/>
        <geom name="link2" type="capsule" fromto="0 0 0 0 0 0.3" size="0.03"/>
        <body name="link3" pos="0 0 0.3">
          <joint name="j3" axis="0 1 0" range="-0.2 2.5"/>
          <geom name="link3" type="capsule" fromto="0 0 0 0 0 0.25" size="0.025"/>
          <body name="link4" pos="0 0 0.25">
            <joint name="j4" axis="0 1 0" range="-2.5 2.5"/>
            <geom name="link4" type="cylinder" fromto="0 0 0 0 0 0.15" size="0.02"/>
            <site name="tool" pos="0 0 0.15"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  <actuator>
    <position name="a1" joint="j1" kp="50"/>
    <position name="a2" joint="j2" kp="50"/>
    <position name="a3" joint="j3" kp="30"/>
    <position name="a4" joint="j4" kp="10"/>
  </actuator>
  <keyframe>
    <key name="rest" qpos="0.6 0.6 0.2 1 0 0 0  0.4 0.8 1.0 0.5"/>
  </keyframe>
</mujoco>
"""
JOINTS = ("j1", "j2", "j3", "j4")
REST = np.array([0.4, 0.8, 1.0, 0.5])
#: The x and z rows of position(tool): the plane the tool moves in.
PLANE = np.array([1.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def arm() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(PLANAR_ARM)


@pytest.fixture
def data(arm: mujoco.MjModel) -> mujoco.MjData:
    data = mujoco.MjData(arm)
    mujoco.mj_resetDataKeyframe(arm, data, 0)
    mujoco.mj_forward(arm, data)
    return data


def fd_jacobian(task_map, model, data, eps=1e-6) -> np.ndarray:
    """Central differences over the tangent space at data.qpos (mj_integratePos)."""
    q0 = data.qpos.copy()
    J = np.zeros((task_map.dim, model.nv))
    for k in range(model.nv):
        ys = []
        for sign in (1.0, -1.0):
            data.qpos[:] = q0
            mujoco.mj_integratePos(model, data.qpos, np.eye(model.nv)[k], sign * eps)
            mujoco.mj_kinematics(model, data)
            mujoco.mj_comPos(model, data)
            ys.append(task_map(model, data).y)
        J[:, k] = task_map.difference(*ys) / (2 * eps)
    data.qpos[:] = q0
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    return J


def tool(model, data, q) -> np.ndarray:
    forward_kinematics(model, data, q)
    return data.site("tool").xpos.copy()


# Kinematics


def test_default_joints_are_the_hinges_not_the_free_joint(arm, data, rng):
    assert controlled_joints(arm) == JOINTS
    np.testing.assert_array_equal(arm_qpos_indices(arm), [7, 8, 9, 10])
    np.testing.assert_array_equal(arm_dof_indices(arm), [6, 7, 8, 9])
    np.testing.assert_array_equal(joint_limits(arm)[2], [-0.2, 2.5])
    qs = random_configurations(arm, rng, 200)
    assert (
        qs.shape == (200, 4)
        and (qs >= joint_limits(arm)[:, 0]).all()
        and (qs <= joint_limits(arm)[:, 1]).all()
    )
    ball = data.qpos[:7].copy()
    forward_kinematics(arm, data, qs[0])
    np.testing.assert_array_equal(data.qpos[7:], qs[0])
    np.testing.assert_array_equal(data.qpos[:7], ball)
    forward_kinematics(arm, data, [0.1, 0.2], joints=("j2", "j4"))
    np.testing.assert_array_equal(data.qpos[[8, 10]], [0.1, 0.2])
    with pytest.raises(ValueError, match="4 finite joint angles"):
        forward_kinematics(arm, data, np.zeros(6))


def test_tool_position_matches_planar_forward_kinematics(arm, data, rng):
    """x = sum_i l_i sin(theta_i), z = 0.05 + sum_i l_i cos(theta_i), theta_i = q_1 + ... + q_i."""
    lengths = np.array([0.3, 0.3, 0.25, 0.15])
    for q in random_configurations(arm, rng, 20):
        theta = np.cumsum(q)
        expected = [lengths @ np.sin(theta), 0.0, 0.05 + lengths @ np.cos(theta)]
        np.testing.assert_allclose(tool(arm, data, q), expected, atol=1e-12)


# Task maps


@pytest.mark.parametrize(
    "spec",
    [
        "position(tool)",
        "quaternion(tool)",
        "positionRel(tool, link2)",
        "scalarProductZZ(world, tool)",
        "vectorX(tool)",
        "jointState",
        "jointLimits",
        "distance(link3, ground)",
        "distance(link4, ground)",
    ],
)
def test_jacobians_match_finite_differences(arm, data, rng, spec):
    task_map = parse_spec(spec, arm)
    for q in random_configurations(arm, rng, 6):
        forward_kinematics(arm, data, q)
        y, J = task_map(arm, data)
        if spec.startswith("distance") and abs(y[0]) < 1e-3:  # touching: not smooth
            continue
        atol = 1e-5 if spec.startswith("distance") and y[0] < 0 else 1e-6  # MuJoCo's depth tolerance
        np.testing.assert_allclose(J, fd_jacobian(task_map, arm, data), atol=atol)


def test_joint_maps_read_the_joints_given_to_the_parser(arm, data):
    stack = parse_spec("jointState, jointLimits", arm, joints=("j3", "j1"))
    y, J = stack(arm, data)
    np.testing.assert_array_equal(y[:2], [1.0, 0.4])
    np.testing.assert_allclose(y[2:], [-0.2 - 1.0, -2.5 - 0.4, 1.0 - 2.5, 0.4 - 2.5])
    np.testing.assert_array_equal(J[0], np.eye(10)[8])  # j3's dof
    assert parse_spec("jointState", arm).dim == 4
    with pytest.raises(InvalidConfig, match="joint 'ball' is a free joint"):
        parse_spec("jointState", arm, joints=("ball",))


# IK


def test_solves_reachable_targets_within_the_limits(arm, data, rng):
    task_map = parse_spec("position(tool)", arm)
    solver = DlsSolver(arm, task_map, JOINTS, IKOptions(tol=1e-6))
    for q in random_configurations(arm, rng, 20):
        target = tool(arm, data, q)
        mujoco.mj_resetDataKeyframe(arm, data, 0)
        result = solver.solve(data, target)
        assert result.converged, f"target from {q}"
        assert (result.q >= solver.lower).all() and (result.q <= solver.upper).all()
        np.testing.assert_allclose(tool(arm, data, result.q), target, atol=1e-6)


def test_posture_term_moves_the_elbow_without_moving_the_tool(arm, data):
    """Control steps with the tool's target where it is: the arm folds toward the rest posture."""
    task_map = parse_spec("position(tool)", arm)
    start = np.array([0.1, 0.2, 0.3, 1.5])
    target = tool(arm, data, start)
    solver = DlsSolver(arm, task_map, JOINTS, IKOptions(posture=tuple(REST), posture_gain=0.2))
    q = start.copy()
    for _ in range(100):
        forward_kinematics(arm, data, q)
        q, _ = solver.step(q, task_map(arm, data), target)
    np.testing.assert_allclose(tool(arm, data, q), target, atol=1e-6)
    elbow = data.body("link3").xpos.copy()
    forward_kinematics(arm, data, start)
    assert np.linalg.norm(elbow - data.body("link3").xpos) > 0.05  # the elbow moved by > 5 cm
    assert np.linalg.norm(q - REST) < 0.6 * np.linalg.norm(start - REST)


def test_posture_gain_per_joint_weights_the_pull(arm, data):
    """A zero gain keeps a joint out of the posture term: only the weighted joints are pulled."""
    task_map = parse_spec("position(tool)", arm)
    start = np.array([0.1, 0.2, 0.3, 1.5])
    target = tool(arm, data, start)
    pulled = {}
    for gains in ((0.2, 0.2, 0.2, 0.2), (0.0, 0.0, 0.0, 0.2)):
        solver = DlsSolver(arm, task_map, JOINTS, IKOptions(posture=tuple(REST), posture_gain=gains))
        forward_kinematics(arm, data, start)
        q, _ = solver.step(start, task_map(arm, data), target)
        pulled[gains[0]] = q - start
    # d = k (rest - q) is zero on joints with gain 0, so the step is the task's (zero here) projected
    # part of the wrist's pull alone, smaller than the full pull.
    assert np.linalg.norm(pulled[0.0]) < np.linalg.norm(pulled[0.2])


def test_steps_stay_within_the_limits_and_hold_the_tool(arm, data):
    """A rest posture beyond j3's lower limit: j3 stops at the limit, the tool stays put."""
    task_map = parse_spec("position(tool)", arm)
    start = np.array([0.1, 0.2, 0.3, 1.5])
    target = tool(arm, data, start)
    beyond = (0.4, 0.8, -1.5, 0.5)
    solver = DlsSolver(arm, task_map, JOINTS, IKOptions(posture=beyond, posture_gain=0.3))
    q = start.copy()
    for _ in range(100):
        forward_kinematics(arm, data, q)
        q, _ = solver.step(q, task_map(arm, data), target)
        assert (q >= solver.lower).all() and (q <= solver.upper).all()
    assert q[2] == pytest.approx(-0.2)
    np.testing.assert_allclose(tool(arm, data, q), target, atol=1e-6)


def test_a_joint_at_its_limit_is_held_and_the_others_meet_the_task(arm, data):
    """The plain DLS step would drive j3 below its limit; the step holds j3 there and uses the others."""
    task_map = parse_spec("position(tool)", arm)
    start = np.array([0.3, 0.4, -0.2, 0.4])  # j3 at its lower limit
    solver = DlsSolver(arm, task_map, JOINTS, IKOptions(damping=1e-6, adaptive_damping=0.0))
    forward_kinematics(arm, data, start)
    value = task_map(arm, data)
    J = value.J[:, 6:]
    target = value.y - 0.1 * J[:, 2]  # where turning j3 below its limit would move the tool
    plain = J.T @ np.linalg.solve(J @ J.T + 1e-6 * np.eye(3), target - value.y)
    assert plain[2] < -0.01  # what clipping would cut off
    q_next, residual = solver.step(start, value, target)
    assert q_next[2] == -0.2
    assert residual < 1e-3 * np.linalg.norm(target - value.y)  # the free joints take over the task


# Robot


def test_robot_from_the_model(arm):
    robot = Robot.from_model(arm, tcp="tool", home="rest", name="planar4")
    assert robot.joints == JOINTS and robot.actuators == ("a1", "a2", "a3", "a4")
    np.testing.assert_array_equal(robot.home_q(arm), REST)
    with pytest.raises(
        UnknownName, match="unknown frame 'tcp'; the model's frames: ball, link1, .*, tool, world"
    ):
        Robot.from_model(arm, tcp="tcp")
    with pytest.raises(UnknownName, match="unknown keyframe 'home'; the model's keyframes: rest"):
        Robot.from_model(arm, tcp="tool", home="home")
    with pytest.raises(UnknownName, match="unknown joint 'elbow'; the model's joints: ball, j1, j2"):
        Robot.from_model(arm, tcp="tool", joints=("j1", "elbow"))
    with pytest.raises(InvalidConfig, match="actuator 'a2' does not drive joint 'j1'"):
        Robot.from_model(arm, tcp="tool", joints=("j1", "j2"), actuators=("a2", "a1"))


def test_the_arm_without_its_servos_gets_them_and_settles_in_its_plane():
    """The same arm with its actuators and keyframe removed: tsrl adds a servo per joint (home given as
    joint values) and a 5 cm step settles in x and z; y, out of the arm's plane, is skipped."""
    bare = PLANAR_ARM.split("  <actuator>")[0] + "</mujoco>"
    spec = mujoco.MjSpec.from_string(bare)
    robot = Robot(name="planar4", model="planar4.xml", joints=JOINTS, tcp="tool", home=tuple(REST))
    arm = prepare_spec(spec, robot, "planar4.toml")
    model = spec.compile()
    assert arm.servos == tuple(servo_name(j) for j in JOINTS) and model.nu == 4
    result = settle(model, JOINTS, "tool", REST, model.key(HOME_KEY).id)
    assert result.ok, result.summary()
    assert [r.direction for r in result.responses] == ["+x", "+z", "-x", "-z"]
    assert result.skipped == ("+y", "-y") and "+y, -y skipped" in result.summary()
    np.testing.assert_array_equal(model.key_qpos[model.key(HOME_KEY).id][7:], REST)  # after the ball
