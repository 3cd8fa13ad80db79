"""The Panda with the Franka Hand (panda_gripper.xml): the arm is panda.xml's, the hand's published facts
(mass, finger travel, TCP, rated grasp force), and real MuJoCo physics: the fingers reach their range
ends together, squeeze the pick-and-place box with the rated force, and hold it when it is lifted."""

import copy

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model, panda
from tsrl.ik import DlsSolver, IKOptions
from tsrl.kinematics import name_to_id
from tsrl.robots import ROBOTS
from tsrl.taskmaps import parse_spec

ROBOT = ROBOTS["panda_gripper"]
#: The TCP pointing down, turned as at home (x along world +y), as the scenes' goal marker.
DOWN = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0])
CONTROL_PERIOD = 0.04  # s
BOX_HALF = 0.02  # m, the pick-and-place box


def steps(model, data, seconds):
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)


def finger_q(model, data):
    """(q_left, q_right) [m]."""
    return tuple(
        float(data.qpos[model.jnt_qposadr[name_to_id(model, "joint", j)]]) for j in panda.FINGER_JOINTS
    )


def finger_box_forces(model, data):
    """Sum of the contact normal forces [N] between each finger and the box: (left, right)."""
    box = name_to_id(model, "geom", "box")
    fingers = [name_to_id(model, "geom", g) for g in panda.FINGER_JOINTS]  # geoms named as the joints
    totals, f6 = [0.0, 0.0], np.zeros(6)
    for i in range(data.ncon):
        pair = set(data.contact.geom[i].tolist())
        for k, g in enumerate(fingers):
            if pair == {g, box}:
                mujoco.mj_contactForce(model, data, i, f6)
                totals[k] += f6[0]
    return tuple(totals)


def tcp_in_hand_frame(model, data, body="box"):
    """Position [m] of `body` in the TCP frame."""
    tcp = name_to_id(model, "site", "tcp")
    R = data.site_xmat[tcp].reshape(3, 3)
    return R.T @ (data.xpos[name_to_id(model, "body", body)] - data.site_xpos[tcp])


def move_smoothly(model, data, q_goal, seconds):
    """Arm servo targets from the current ones to q_goal (7,) along a smooth step, every physics step."""
    q0 = data.ctrl[:7].copy()
    n = round(seconds / model.opt.timestep)
    for i in range(1, n + 1):
        s = i / n
        data.ctrl[:7] = q0 + (3 * s * s - 2 * s * s * s) * (q_goal - q0)
        mujoco.mj_step(model, data)


def arm_for_tcp(model, data, position):
    """Arm angles (7,) with the TCP at `position`, pointing down (an IK solve from the current pose)."""
    pose = parse_spec("position(tcp), quaternion(tcp)", model, ROBOT.joints)
    ik = DlsSolver(model, pose, ROBOT.joints, IKOptions(restarts=0, max_iters=200, tol=1e-7))
    scratch = copy.copy(data)
    result = ik.solve(scratch, np.concatenate([position, DOWN]))
    assert result.converged, result.error_norm
    return result.q


@pytest.fixture(scope="module")
def pick_place():
    return load_model("panda_gripper_pick_place")


@pytest.fixture(scope="module")
def grasped(pick_place):
    """The box squeezed by the closed fingers (control 0) at the TCP, on the table, settled."""
    model = pick_place
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    steps(model, data, 0.3)  # the box settles on the table
    box = data.xpos[name_to_id(model, "body", "box")].copy()
    move_smoothly(model, data, arm_for_tcp(model, data, box + [0, 0, 0.1]), 1.0)
    move_smoothly(model, data, arm_for_tcp(model, data, box), 1.0)
    steps(model, data, 0.3)
    data.ctrl[name_to_id(model, "actuator", ROBOT.gripper)] = 0.0
    steps(model, data, 1.0)
    return model, data


def test_the_arm_is_panda_xml_arm():
    arm, gripper = load_model("panda"), load_model("panda_gripper")
    for body in ("link0", *panda.BODY_NAMES):
        a, g = name_to_id(arm, "body", body), name_to_id(gripper, "body", body)
        for field in (
            "body_pos",
            "body_quat",
            "body_mass",
            "body_ipos",
            "body_iquat",
            "body_inertia",
            "body_gravcomp",
        ):
            np.testing.assert_array_equal(
                getattr(gripper, field)[g], getattr(arm, field)[a], err_msg=f"{field} {body}"
            )
        geoms_a = [arm.geom(i).name for i in range(arm.ngeom) if arm.geom_bodyid[i] == a]
        geoms_g = [gripper.geom(i).name for i in range(gripper.ngeom) if gripper.geom_bodyid[i] == g]
        assert geoms_g == geoms_a
        for name in geoms_a:
            i, k = name_to_id(arm, "geom", name), name_to_id(gripper, "geom", name)
            for field in (
                "geom_type",
                "geom_size",
                "geom_pos",
                "geom_quat",
                "geom_contype",
                "geom_conaffinity",
            ):
                np.testing.assert_array_equal(getattr(gripper, field)[k], getattr(arm, field)[i])
    for joint in panda.JOINT_NAMES:
        a, g = name_to_id(arm, "joint", joint), name_to_id(gripper, "joint", joint)
        np.testing.assert_array_equal(gripper.jnt_range[g], arm.jnt_range[a])
        np.testing.assert_array_equal(gripper.jnt_actgravcomp[g], arm.jnt_actgravcomp[a])
        for field in ("dof_armature", "dof_damping", "dof_frictionloss"):
            np.testing.assert_array_equal(
                getattr(gripper, field)[gripper.jnt_dofadr[g]], getattr(arm, field)[arm.jnt_dofadr[a]]
            )
        a, g = name_to_id(arm, "actuator", joint), name_to_id(gripper, "actuator", joint)
        for field in ("actuator_gainprm", "actuator_biasprm", "actuator_ctrlrange", "actuator_forcerange"):
            np.testing.assert_array_equal(getattr(gripper, field)[g], getattr(arm, field)[a])
    np.testing.assert_array_equal(
        gripper.site_pos[name_to_id(gripper, "site", "flange")],
        arm.site_pos[name_to_id(arm, "site", "flange")],
    )
    assert gripper.opt.timestep == arm.opt.timestep and gripper.opt.integrator == arm.opt.integrator


def test_hand_and_finger_masses_are_the_published_ones():
    model = load_model("panda_gripper")
    bodies = [name_to_id(model, "body", b) for b in ("hand", *panda.FINGER_JOINTS)]
    assert model.body_mass[bodies].sum() == pytest.approx(panda.HAND_MASS, abs=1e-12)
    for finger in bodies[1:]:
        assert model.body_mass[finger] == pytest.approx(panda.FINGER_MASS, abs=1e-12)
        assert model.body_gravcomp[finger] == 1.0  # the configured end-effector load, as the arm's links
    assert model.body_gravcomp[bodies[0]] == 1.0


def test_tcp_and_hand_mounting_relative_to_the_flange(rng):
    model = load_model("panda_gripper")
    data = mujoco.MjData(model)
    flange, tcp = name_to_id(model, "site", "flange"), name_to_id(model, "site", "tcp")
    c, s = np.cos(panda.HAND_YAW), np.sin(panda.HAND_YAW)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    for q in rng.uniform(panda.JOINT_LIMITS[:, 0], panda.JOINT_LIMITS[:, 1], (20, 7)):
        data.qpos[:7] = q
        mujoco.mj_kinematics(model, data)
        R_f = data.site_xmat[flange].reshape(3, 3)
        np.testing.assert_allclose(
            R_f.T @ (data.site_xpos[tcp] - data.site_xpos[flange]), [0, 0, panda.HAND_TCP_OFFSET], atol=1e-12
        )
        np.testing.assert_allclose(R_f.T @ data.site_xmat[tcp].reshape(3, 3), Rz, atol=1e-12)
        for finger in panda.FINGER_JOINTS:  # the finger joints slide along the hand's y axis
            j = name_to_id(model, "joint", finger)
            b = model.jnt_bodyid[j]
            np.testing.assert_allclose(
                R_f.T @ (data.xpos[b] - data.site_xpos[flange]), [0, 0, panda.FINGER_OFFSET], atol=1e-12
            )


def test_home_tcp_frame_is_the_suction_pandas():
    gripper, suction = load_model("panda_gripper_reach"), load_model("panda_reach")
    poses = []
    for model in (gripper, suction):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
        mujoco.mj_kinematics(model, data)
        tcp = name_to_id(model, "site", "tcp")
        poses.append((data.site_xpos[tcp].copy(), data.site_xmat[tcp].reshape(3, 3).copy(), data))
    np.testing.assert_allclose(poses[0][1], poses[1][1], atol=1e-12)
    np.testing.assert_allclose(poses[0][0], panda.GRIPPER_HOME_TCP, atol=1e-7)
    np.testing.assert_allclose(
        poses[0][0], panda.HOME_TCP - [0, 0, panda.HAND_TCP_OFFSET - panda.TCP_OFFSET], atol=1e-7
    )
    data = poses[0][2]
    np.testing.assert_allclose(data.qpos[:7], panda.GRIPPER_HOME_Q)
    np.testing.assert_allclose(finger_q(gripper, data), (panda.FINGER_TRAVEL, panda.FINGER_TRAVEL))  # open
    target = name_to_id(gripper, "body", "target")
    np.testing.assert_allclose(gripper.body_pos[target], panda.GRIPPER_HOME_TCP, atol=1e-4)


def test_robot_entry_names_the_gripper_servo():
    model = ROBOT.load_model()
    assert ROBOT.suction is None
    a = name_to_id(model, "actuator", ROBOT.gripper)
    assert int(model.actuator_trntype[a]) == int(mujoco.mjtTrn.mjTRN_TENDON)
    tendon = model.actuator_trnid[a, 0]
    adr, num = model.tendon_adr[tendon], model.tendon_num[tendon]
    joints = {model.joint(model.wrap_objid[k]).name: model.wrap_prm[k] for k in range(adr, adr + num)}
    assert joints == {"finger_left": 1.0, "finger_right": 1.0}  # its length is the opening width
    np.testing.assert_allclose(model.actuator_ctrlrange[a], [0.0, panda.MAX_WIDTH])
    np.testing.assert_allclose(model.actuator_forcerange[a], [-panda.GRASP_FORCE, panda.GRASP_FORCE])
    for finger in panda.FINGER_JOINTS:
        np.testing.assert_allclose(
            model.jnt_range[name_to_id(model, "joint", finger)], [0.0, panda.FINGER_TRAVEL]
        )
    for scene in ("panda_gripper_reach", "panda_gripper_pick_place"):
        ROBOT.validate(load_model(scene))


@pytest.mark.parametrize(("start", "command"), [(panda.MAX_WIDTH, 0.0), (0.0, panda.MAX_WIDTH)])
def test_fingers_travel_together_to_their_range_ends(start, command):
    """From one end of the servo's range to the other: each finger ends at 0 or 40 mm, the fingers'
    inner faces `command` apart (measured between the geoms), and the two move as one all the way."""
    model = load_model("panda_gripper_reach")
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    for j in panda.FINGER_JOINTS:
        data.qpos[model.jnt_qposadr[name_to_id(model, "joint", j)]] = start / 2
    gripper = name_to_id(model, "actuator", ROBOT.gripper)
    data.ctrl[gripper] = command
    worst_mismatch = 0.0
    for _ in range(round(1.0 / model.opt.timestep)):
        mujoco.mj_step(model, data)
        left, right = finger_q(model, data)
        worst_mismatch = max(worst_mismatch, abs(left - right))
    left, right = finger_q(model, data)
    assert left == pytest.approx(command / 2, abs=1e-4) and right == pytest.approx(command / 2, abs=1e-4)
    assert worst_mismatch < 1e-5
    mujoco.mj_forward(model, data)
    faces = [name_to_id(model, "geom", g) for g in panda.FINGER_JOINTS]
    gap = mujoco.mj_geomDistance(model, data, faces[0], faces[1], 1.0, None)
    assert gap == pytest.approx(left + right, abs=1e-9)
    assert data.actuator_length[gripper] == pytest.approx(left + right, abs=1e-12)


def test_closed_fingers_squeeze_the_box_with_the_rated_grasp_force(grasped):
    model, data = grasped
    gripper = name_to_id(model, "actuator", ROBOT.gripper)
    assert data.actuator_force[gripper] == pytest.approx(-panda.GRASP_FORCE)  # saturated: 70 N per finger
    left, right = finger_box_forces(model, data)
    assert left == pytest.approx(panda.GRASP_FORCE, rel=0.01)
    assert right == pytest.approx(panda.GRASP_FORCE, rel=0.01)
    width = sum(finger_q(model, data))
    assert 2 * BOX_HALF - 1e-3 < width < 2 * BOX_HALF  # the contacts are stiff: < 0.5 mm per finger
    np.testing.assert_allclose(tcp_in_hand_frame(model, data), 0.0, atol=1e-3)  # centred by the coupling


def test_oppose_of_the_grasped_box_is_near_zero(grasped):
    """The coupled fingers centre the box they squeeze: RAI's opposition is below 0.1 mm."""
    model, data = grasped
    y = parse_spec("oppose(finger_left, finger_right, box)", model)(model, data).y
    assert np.linalg.norm(y) < 1e-4
    shifted = copy.copy(data)  # the same grasp with the box 2 mm towards finger_left: y = -4 mm there
    R = data.site_xmat[name_to_id(model, "site", "tcp")].reshape(3, 3)
    adr = model.jnt_qposadr[name_to_id(model, "joint", "box")]
    shifted.qpos[adr : adr + 3] += 0.002 * R[:, 1]
    mujoco.mj_kinematics(model, shifted)
    mujoco.mj_comPos(model, shifted)
    y_shifted = parse_spec("oppose(finger_left, finger_right, box)", model)(model, shifted).y
    np.testing.assert_allclose(y_shifted - y, -0.004 * R[:, 1], atol=1e-5)


def test_a_width_target_inside_the_box_squeezes_below_the_rating(grasped):
    """3 mm inside the box the servo's force is below its limit, and the fingers press with that force."""
    model, data = grasped
    data = copy.copy(data)
    gripper = name_to_id(model, "actuator", ROBOT.gripper)
    data.ctrl[gripper] = 2 * BOX_HALF - 0.003
    steps(model, data, 0.5)
    force = -data.actuator_force[gripper]
    assert 0.2 * panda.GRASP_FORCE < force < 0.8 * panda.GRASP_FORCE
    left, right = finger_box_forces(model, data)
    assert left == pytest.approx(force, rel=0.01) and right == pytest.approx(force, rel=0.01)


def test_the_lifted_box_is_held_against_gravity(grasped):
    model, data = grasped
    data = copy.copy(data)
    box = name_to_id(model, "body", "box")
    z0, in_hand = data.xpos[box][2], tcp_in_hand_frame(model, data)
    tcp = data.site_xpos[name_to_id(model, "site", "tcp")].copy()
    move_smoothly(model, data, arm_for_tcp(model, data, tcp + [0, 0, 0.15]), 1.5)
    lifted = tcp_in_hand_frame(model, data)
    assert data.xpos[box][2] - z0 == pytest.approx(0.15, abs=1e-3)
    assert np.linalg.norm(lifted - in_hand) < 5e-4  # no slip in the lift
    assert not any(
        {model.geom(g).name for g in data.contact.geom[i]} & {"table"} for i in range(data.ncon)
    )  # in the air
    steps(model, data, 2.0)
    assert np.linalg.norm(tcp_in_hand_frame(model, data) - lifted) < 1e-4  # nor in two seconds of holding


def test_gravity_compensation_with_the_hand_fits_in_the_torque_limits(rng):
    model = load_model("panda_gripper")
    data = mujoco.MjData(model)
    for q in rng.uniform(panda.JOINT_LIMITS[:, 0], panda.JOINT_LIMITS[:, 1], (200, 7)):
        data.qpos[:7] = q
        mujoco.mj_forward(model, data)
        assert np.all(np.abs(data.qfrc_gravcomp[:7]) < 0.7 * panda.MAX_JOINT_TORQUES)
