"""Map values against independent computations: plain DH kinematics, geometry and joint ranges."""

from __future__ import annotations

import pickle

import mujoco
import numpy as np
import pytest

from tsrl.assets.ur5e import HOME_Q, JOINT_LIMITS, TCP_OFFSET, UR5E_DH
from tsrl.envs import parse_observation
from tsrl.kinematics import dh_forward, forward_kinematics, random_configurations
from tsrl.taskmaps import parse_spec
from tsrl.taskmaps.position import negative_skew, skew

from .conftest import finite_difference_jacobian, set_qpos


def _mat2quat(R: np.ndarray) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, R.flatten())
    return q


def test_positions_and_axes_match_dh(ur5e, rng):
    model, data = ur5e
    stack = parse_spec(
        "position(flange), position(tcp), vectorX(tcp), vectorY(tcp), vectorZ(tcp), positionRel(tcp, flange)",
        model,
    )
    s = stack.slices
    for q in random_configurations(model, rng, 20):
        forward_kinematics(model, data, q)
        y = stack(model, data).y
        T = dh_forward(UR5E_DH, q)  # flange = DH frame 6; tcp = flange + 0.07 z, same orientation
        np.testing.assert_allclose(y[s["position(flange)"]], T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(y[s["position(tcp)"]], T[:3, 3] + TCP_OFFSET * T[:3, 2], atol=1e-9)
        for i, axis in enumerate("XYZ"):
            np.testing.assert_allclose(y[s[f"vector{axis}(tcp)"]], T[:3, i], atol=1e-9)
        np.testing.assert_allclose(y[s["positionRel(tcp, flange)"]], [0, 0, TCP_OFFSET], atol=1e-9)


def test_scalar_products_are_dot_products_of_dh_axes(ur5e, rng):
    model, data = ur5e
    specs = [f"scalarProduct{a}{b}(upper_arm_link, tcp)" for a in "XYZ" for b in "XYZ"]
    stack = parse_spec(", ".join(specs), model)
    for q in random_configurations(model, rng, 10):
        forward_kinematics(model, data, q)
        # upper_arm_link is DH frame 1 turned by joint 2: the orientation of DH frame 2 (alpha_2 = 0).
        R_f = dh_forward(UR5E_DH[:2], q[:2])[:3, :3]
        R_t = dh_forward(UR5E_DH, q)[:3, :3]
        np.testing.assert_allclose(stack(model, data).y, (R_f.T @ R_t).flatten(), atol=1e-9)


def test_world_frame_is_the_identity_with_zero_jacobian(ur5e, rng):
    model, data = ur5e
    stack = parse_spec("position(world), quaternion(world), vectorZ(world), positionRel(tcp, world)", model)
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    y, J = stack(model, data)
    np.testing.assert_array_equal(y[:10], [0, 0, 0, 1, 0, 0, 0, 0, 0, 1])
    np.testing.assert_array_equal(J[:10], 0.0)
    np.testing.assert_allclose(y[10:], data.site("tcp").xpos)


def test_cup_points_down_at_home(ur5e):
    model, data = ur5e
    y = parse_spec("scalarProductZZ(world, tcp)", model)(model, data).y
    np.testing.assert_allclose(y, [-1.0], atol=1e-12)


def test_quaternion_matches_dh_rotation_up_to_sign(ur5e, rng):
    model, data = ur5e
    stack = parse_spec("quaternion(flange), quaternion(tcp)", model)
    for q in random_configurations(model, rng, 20):
        forward_kinematics(model, data, q)
        y = stack(model, data).y
        expected = _mat2quat(dh_forward(UR5E_DH, q)[:3, :3])
        for quat in (y[:4], y[4:]):
            assert np.linalg.norm(quat) == pytest.approx(1.0)
            assert min(np.abs(quat - expected).max(), np.abs(quat + expected).max()) < 1e-9


@pytest.mark.parametrize("joint", range(6))
def test_quaternion_is_continuous_along_a_full_joint_sweep(joint, ur5e, rng):
    model, data = ur5e
    quaternion = parse_spec("quaternion(tcp)", model)
    q = random_configurations(model, rng, 1)[0]
    angles = np.linspace(*JOINT_LIMITS[joint], 721)
    ys, rederived = [], []
    for angle in angles:
        q[joint] = angle
        forward_kinematics(model, data, q)
        ys.append(quaternion(model, data).y)
        rederived.append(_mat2quat(data.site("tcp").xmat.reshape(3, 3)))
    step = angles[1] - angles[0]  # a rotation by step moves a unit quaternion by ~step / 2
    assert np.abs(np.diff(ys, axis=0)).max() < step
    if joint == 0:  # the sweep does cross a point where a quaternion from the matrix flips sign
        assert np.abs(np.diff(rederived, axis=0)).max() > 0.5


def test_quaternion_difference_ignores_the_double_cover(ur5e):
    model, data = ur5e
    quaternion = parse_spec("quaternion(tcp)", model)
    y = quaternion(model, data).y
    np.testing.assert_allclose(quaternion.difference(y, -y), 0.0)
    np.testing.assert_allclose(quaternion.difference(np.stack([y, y]), np.stack([-y, y])), 0.0)


def test_quaternion_diff_follows_rai_sign_rule(ur5e, rng):
    model, data = ur5e
    stack = parse_spec(
        "quaternion(tcp), quaternion(upper_arm_link), quaternionDiff(tcp, upper_arm_link)", model
    )
    for q in random_configurations(model, rng, 10):
        forward_kinematics(model, data, q)
        y = stack(model, data).y
        q_f, q_g = y[:4], y[4:8]
        np.testing.assert_allclose(y[8:], q_f - np.sign(q_f @ q_g) * q_g, atol=1e-12)


def test_distance_is_positive_apart_and_negative_penetrating(ur5e, pressed_q):
    model, data = ur5e
    distance = parse_spec("distance(suction_cup, table)", model)
    forward_kinematics(model, data, HOME_Q)
    # At home the cup points down; its tip (tcp) is the lowest point, the table top is z = 0.
    assert distance(model, data).y[0] == pytest.approx(data.site("tcp").xpos[2], abs=1e-6)
    forward_kinematics(model, data, pressed_q)  # tip 4 mm below the top, cup tilted by 0.1 rad
    assert distance(model, data).y[0] == pytest.approx(-(0.004 + 0.02 * np.sin(0.1)), abs=1e-5)


def test_distance_is_symmetric(ur5e, pressed_q):
    model, data = ur5e
    stack = parse_spec("distance(suction_cup, table), distance(table, suction_cup)", model)
    for q in (HOME_Q, pressed_q):
        forward_kinematics(model, data, q)
        y, J = stack(model, data)
        np.testing.assert_allclose(y[0], y[1], atol=1e-9)
        np.testing.assert_allclose(J[0], J[1], atol=1e-6)


def test_accumulated_collisions_is_the_penetration_depth(ur5e, pressed_q):
    model, data = ur5e
    stack = parse_spec("accumulatedCollisions, distance(suction_cup, table)", model)
    forward_kinematics(model, data, HOME_Q)
    y, J = stack(model, data)
    assert y[0] == 0.0 and data.ncon == 0
    np.testing.assert_array_equal(J[0], 0.0)
    forward_kinematics(model, data, pressed_q)  # only the cup touches: one contact
    y, J = stack(model, data)
    assert data.ncon == 1 and y[0] > 0.0
    np.testing.assert_allclose(y[0], -y[1], atol=1e-6)
    np.testing.assert_allclose(J[0], -J[1], atol=1e-6)


def test_joint_state_and_limits(ur5e, rng):
    model, data = ur5e
    stack = parse_spec("jointState, jointLimits", model)
    for q in random_configurations(model, rng, 10):
        forward_kinematics(model, data, q)
        y = stack(model, data).y
        np.testing.assert_allclose(y[:6], q)
        np.testing.assert_allclose(y[6:], np.concatenate([JOINT_LIMITS[:, 0] - q, q - JOINT_LIMITS[:, 1]]))
        assert np.all(y[6:] <= 0.0)
    q = HOME_Q.copy()
    q[2] = np.pi + 0.1  # the elbow 0.1 rad past its upper limit
    forward_kinematics(model, data, q)
    margins = stack(model, data).y[6:]
    assert margins[6 + 2] == pytest.approx(0.1)
    assert np.sum(margins > 0) == 1


def test_joint_state_reads_only_the_arm_of_the_pick_place_scene(rng):
    from tsrl.assets import load_model

    model = load_model("pick_place")
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    y, J = parse_spec("jointState", model)(model, data)
    assert y.shape == (6,) and J.shape == (6, model.nv)
    np.testing.assert_array_equal(J[:, 6:], 0.0)  # the box's free joint


def test_returned_arrays_are_fresh(ur5e, rng):
    model, data = ur5e
    stack = parse_observation("fs2", model)
    first = stack(model, data)
    kept = first.y.copy(), first.J.copy()
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    stack(model, data)
    np.testing.assert_array_equal(first.y, kept[0])
    np.testing.assert_array_equal(first.J, kept[1])


def test_static_frames_have_zero_jacobian(ur5e, rng):
    model, data = ur5e
    stack = parse_spec("position(target), quaternion(target), position(world), vectorZ(base)", model)
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    np.testing.assert_array_equal(stack(model, data).J, 0.0)


def test_one_map_on_two_data_objects(reach_model, rng):
    stack = parse_observation("fs2, positionRel(tcp, upper_arm_link)", reach_model)
    datas = [mujoco.MjData(reach_model) for _ in range(2)]
    for data, q in zip(datas, random_configurations(reach_model, rng, 2)):
        forward_kinematics(reach_model, data, q)
    expected = [parse_spec(stack.spec, reach_model)(reach_model, d).y for d in datas]  # fresh maps
    for _ in range(2):  # alternate: the cache re-binds to whichever data it is given
        for data, y in zip(datas, expected):
            np.testing.assert_array_equal(stack(reach_model, data).y, y)


def test_maps_pickle_after_use(ur5e):
    model, data = ur5e
    stack = parse_observation("fs2, distance(suction_cup, table), jointLimits", model)
    y = stack(model, data).y
    clone = pickle.loads(pickle.dumps(stack))
    np.testing.assert_array_equal(clone(model, data).y, y)


ROTATED_SITE_XML = """
<mujoco>
  <compiler angle="radian"/>
  <worldbody>
    <body name="link">
      <joint name="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02"/>
      <body name="tip" pos="0.3 0 0">
        <joint name="twist" axis="1 0 0"/>
        <geom type="sphere" size="0.02"/>
        <site name="tool" pos="0.05 0 0" euler="0.3 -0.7 1.2"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_site_with_its_own_rotation(rng):
    model = mujoco.MjModel.from_xml_string(ROTATED_SITE_XML)
    data = mujoco.MjData(model)
    quaternion = parse_spec("quaternion(tool), quaternion(tip)", model)
    for q in rng.uniform(-np.pi, np.pi, size=(5, 2)):
        set_qpos(model, data, q)
        y, J = quaternion(model, data)
        expected = np.zeros(4)
        mujoco.mju_mulQuat(expected, data.xquat[model.body("tip").id], model.site_quat[model.site("tool").id])
        np.testing.assert_allclose(y[:4], expected, atol=1e-12)
        assert (
            min(
                np.abs(y[:4] - _mat2quat(data.site("tool").xmat)).max(),
                np.abs(y[:4] + _mat2quat(data.site("tool").xmat)).max(),
            )
            < 1e-9
        )
        assert np.abs(y[:4] - y[4:]).max() > 0.1  # the site is rotated against its body
        np.testing.assert_allclose(J, finite_difference_jacobian(quaternion, model, data), atol=1e-6)


def test_skew_matrices_are_the_cross_product(rng):
    v, w = rng.normal(size=3), rng.normal(size=3)
    np.testing.assert_allclose(skew(v, np.empty((3, 3))) @ w, np.cross(v, w), atol=1e-15)
    np.testing.assert_array_equal(negative_skew(v, np.empty((3, 3))), -skew(v, np.empty((3, 3))))
