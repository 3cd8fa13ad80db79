"""The Franka Hand (panda/hand*.xml) on the Panda (panda_gripper.xml) and on the UR5e (ur5e/ur5e_gripper.xml):
each arm is its suction model's, the hand's published facts (mass, finger travel, TCP, rated grasp force),
and real MuJoCo physics: the fingers reach their range ends together, squeeze an object (the Panda's
pick-and-place box, the UR5e's peg) with the rated force, and hold it when it is lifted."""

import copy
from dataclasses import dataclass
from types import ModuleType

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model, panda, ur5e
from tsrl.ik import DlsSolver, IKOptions
from tsrl.kinematics import name_to_id
from tsrl.robots import ROBOTS, Robot
from tsrl.taskmaps import parse_spec

#: The TCP pointing down, turned as at home (x along world +y), as the scenes' goal marker.
DOWN = np.array([0.0, np.sqrt(0.5), np.sqrt(0.5), 0.0])
CONTROL_PERIOD = 0.04  # s


@dataclass(frozen=True)
class Arm:
    """An arm with the hand: its robot entry, its suction model (the same arm), its facts, and the scene
    and object of the grasp tests."""

    robot: Robot
    suction: str  # the suction model's scene: the same arm
    reach: str  # a scene with the suction arm's goal marker at home
    gripper_reach: str  # the same with the hand
    base: str  # the arm's base body
    facts: ModuleType  # tsrl.assets.panda or ur5e: joints, limits, torques, home
    hand_yaw: float  # rad, the hand's turn about the flange z axis
    home_tcp: np.ndarray  # m, the hand's TCP at home
    grasp_scene: str
    obj: str  # the grasped body (and its geom)
    obj_half: float  # m, half its width between the fingers
    grasp_height: float  # m, the TCP above the object's centre when grasping


ARMS = {
    "panda": Arm(
        ROBOTS["panda_gripper"],
        "panda",
        "panda_reach",
        "panda_gripper_reach",
        "link0",
        panda,
        panda.HAND_YAW,
        panda.GRIPPER_HOME_TCP,
        "panda_gripper_pick_place",
        "box",
        0.02,
        0.0,
    ),
    "ur5e": Arm(
        ROBOTS["ur5e_gripper"],
        "ur5e",
        "reach",
        "ur5e_gripper_peg",
        "base",
        ur5e,
        ur5e.GRIPPER_HAND_YAW,
        ur5e.GRIPPER_HOME_TCP,
        "ur5e_gripper_peg",
        "peg",
        0.01,
        0.02,
    ),
}


@pytest.fixture(scope="module", params=list(ARMS))
def arm(request) -> Arm:
    return ARMS[request.param]


def steps(model, data, seconds):
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)


def finger_q(model, data):
    """(q_left, q_right) [m]."""
    return tuple(
        float(data.qpos[model.jnt_qposadr[name_to_id(model, "joint", j)]]) for j in panda.FINGER_JOINTS
    )


def finger_box_forces(model, data, obj="box"):
    """Sum of the contact normal forces [N] between each finger and the object `obj`: (left, right)."""
    box = name_to_id(model, "geom", obj)
    fingers = [name_to_id(model, "geom", g) for g in panda.FINGER_JOINTS]  # geoms named as the joints
    totals, f6 = [0.0, 0.0], np.zeros(6)
    for i in range(data.ncon):
        pair = set(data.contact.geom[i].tolist())
        for k, g in enumerate(fingers):
            if pair == {g, box}:
                mujoco.mj_contactForce(model, data, i, f6)
                totals[k] += f6[0]
    return tuple(totals)


def tcp_in_hand_frame(model, data, body):
    """Position [m] of `body` in the TCP frame."""
    tcp = name_to_id(model, "site", "tcp")
    R = data.site_xmat[tcp].reshape(3, 3)
    return R.T @ (data.xpos[name_to_id(model, "body", body)] - data.site_xpos[tcp])


def move_smoothly(model, data, q_goal, seconds):
    """Arm servo targets from the current ones to q_goal (n,) along a smooth step, every physics step
    (the arm's servos are the first n actuators)."""
    n_arm = len(q_goal)
    q0 = data.ctrl[:n_arm].copy()
    n = round(seconds / model.opt.timestep)
    for i in range(1, n + 1):
        s = i / n
        data.ctrl[:n_arm] = q0 + (3 * s * s - 2 * s * s * s) * (q_goal - q0)
        mujoco.mj_step(model, data)


def arm_for_tcp(model, data, position, robot):
    """Arm angles (n,) with the TCP at `position`, pointing down (an IK solve from the current pose)."""
    pose = parse_spec("position(tcp), quaternion(tcp)", model, robot.joints)
    ik = DlsSolver(model, pose, robot.joints, IKOptions(restarts=0, max_iters=200, tol=1e-7))
    scratch = copy.copy(data)
    result = ik.solve(scratch, np.concatenate([position, DOWN]))
    assert result.converged, result.error_norm
    return result.q


@pytest.fixture(scope="module")
def grasped(arm):
    """The arm's object squeezed by the closed fingers (control 0) at the TCP, standing on the table,
    settled; returns (model, data, arm)."""
    model = load_model(arm.grasp_scene)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    steps(model, data, 0.3)  # the object settles on the table
    grasp = data.xpos[name_to_id(model, "body", arm.obj)] + [0, 0, arm.grasp_height]
    move_smoothly(model, data, arm_for_tcp(model, data, grasp + [0, 0, 0.1], arm.robot), 1.0)
    move_smoothly(model, data, arm_for_tcp(model, data, grasp, arm.robot), 1.0)
    steps(model, data, 0.3)
    data.ctrl[name_to_id(model, "actuator", arm.robot.gripper)] = 0.0
    steps(model, data, 1.0)
    return model, data, arm


def test_the_arm_is_the_suction_models_arm(arm):
    suction, gripper = load_model(arm.suction), load_model(arm.robot.model)
    for body in (arm.base, *arm.facts.BODY_NAMES):
        a, g = name_to_id(suction, "body", body), name_to_id(gripper, "body", body)
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
                getattr(gripper, field)[g], getattr(suction, field)[a], err_msg=f"{field} {body}"
            )
        geoms_a = [suction.geom(i).name for i in range(suction.ngeom) if suction.geom_bodyid[i] == a]
        geoms_g = [gripper.geom(i).name for i in range(gripper.ngeom) if gripper.geom_bodyid[i] == g]
        assert geoms_g == geoms_a
        for name in geoms_a:
            i, k = name_to_id(suction, "geom", name), name_to_id(gripper, "geom", name)
            for field in (
                "geom_type",
                "geom_size",
                "geom_pos",
                "geom_quat",
                "geom_contype",
                "geom_conaffinity",
                "geom_rgba",
            ):
                np.testing.assert_array_equal(getattr(gripper, field)[k], getattr(suction, field)[i])
    for joint in arm.facts.JOINT_NAMES:
        a, g = name_to_id(suction, "joint", joint), name_to_id(gripper, "joint", joint)
        np.testing.assert_array_equal(gripper.jnt_range[g], suction.jnt_range[a])
        np.testing.assert_array_equal(gripper.jnt_actgravcomp[g], suction.jnt_actgravcomp[a])
        for field in ("dof_armature", "dof_damping", "dof_frictionloss"):
            np.testing.assert_array_equal(
                getattr(gripper, field)[gripper.jnt_dofadr[g]], getattr(suction, field)[suction.jnt_dofadr[a]]
            )
        a, g = name_to_id(suction, "actuator", joint), name_to_id(gripper, "actuator", joint)
        for field in ("actuator_gainprm", "actuator_biasprm", "actuator_ctrlrange", "actuator_forcerange"):
            np.testing.assert_array_equal(getattr(gripper, field)[g], getattr(suction, field)[a])
    np.testing.assert_array_equal(
        gripper.site_pos[name_to_id(gripper, "site", "flange")],
        suction.site_pos[name_to_id(suction, "site", "flange")],
    )
    assert gripper.opt.timestep == suction.opt.timestep and gripper.opt.integrator == suction.opt.integrator
    np.testing.assert_array_equal(gripper.exclude_signature, suction.exclude_signature)  # base link
    # the same arm, the cup's body and actuator gone: the hand's 3 bodies, 7 geoms, 2 joints, 1 servo
    assert gripper.nbody == suction.nbody - 1 + 3 and gripper.ngeom == suction.ngeom - 2 + 4
    assert gripper.njnt == suction.njnt + 2 and gripper.nu == suction.nu
    assert name_to_id(gripper, "actuator", arm.robot.gripper) == gripper.nu - 1  # after the arm's servos


def test_the_hand_is_the_same_on_both_arms():
    """Every hand quantity of the UR5e's equals the Panda's (one set of files)."""
    p, u = load_model("panda_gripper"), load_model("ur5e_gripper")
    for kind, names, fields in (
        ("body", ("hand", *panda.FINGER_JOINTS), ("body_mass", "body_inertia", "body_ipos", "body_gravcomp")),
        (
            "geom",
            ("hand_adapter", "hand", *panda.FINGER_JOINTS),
            (
                "geom_size",
                "geom_pos",
                "geom_friction",
                "geom_solref",
                "geom_solimp",
                "geom_solmix",
                "geom_rgba",
            ),
        ),
        ("joint", panda.FINGER_JOINTS, ("jnt_range", "jnt_axis", "jnt_pos")),
        ("site", ("tcp", *panda.FINGER_JOINTS), ("site_pos", "site_quat")),
        (
            "actuator",
            (panda.GRIPPER_ACTUATOR,),
            ("actuator_gainprm", "actuator_biasprm", "actuator_forcerange"),
        ),
        ("equality", ("fingers",), ("eq_data", "eq_solref", "eq_solimp")),
    ):
        for name in names:
            obj = mujoco.mju_str2Type(kind)
            i, k = mujoco.mj_name2id(p, obj, name), mujoco.mj_name2id(u, obj, name)
            assert i >= 0 and k >= 0, name
            for field in fields:
                np.testing.assert_array_equal(
                    getattr(u, field)[k], getattr(p, field)[i], err_msg=f"{field} {name}"
                )
    for field in ("dof_armature", "dof_damping"):
        np.testing.assert_array_equal(getattr(u, field)[-2:], getattr(p, field)[-2:])
    assert (
        (u.opt.cone, u.opt.impratio)
        == (p.opt.cone, p.opt.impratio)
        == (int(mujoco.mjtCone.mjCONE_ELLIPTIC), 10)
    )


def test_hand_and_finger_masses_are_the_published_ones(arm):
    model = load_model(arm.robot.model)
    bodies = [name_to_id(model, "body", b) for b in ("hand", *panda.FINGER_JOINTS)]
    assert model.body_mass[bodies].sum() == pytest.approx(panda.HAND_MASS, abs=1e-12)
    for finger in bodies[1:]:
        assert model.body_mass[finger] == pytest.approx(panda.FINGER_MASS, abs=1e-12)
        assert model.body_gravcomp[finger] == 1.0  # the configured end-effector load, as the arm's links
    assert model.body_gravcomp[bodies[0]] == 1.0


def test_tcp_and_hand_mounting_relative_to_the_flange(arm, rng):
    model = load_model(arm.robot.model)
    data = mujoco.MjData(model)
    flange, tcp = name_to_id(model, "site", "flange"), name_to_id(model, "site", "tcp")
    c, s = np.cos(arm.hand_yaw), np.sin(arm.hand_yaw)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    limits = arm.facts.JOINT_LIMITS
    for q in rng.uniform(limits[:, 0], limits[:, 1], (20, len(limits))):
        data.qpos[: len(q)] = q
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


def test_home_tcp_frame_is_the_suction_arms(arm):
    """At home the hand's TCP frame is the suction arm's (x along world +y, z down), HAND_TCP_OFFSET -
    TCP_OFFSET lower, with the fingers open; the gripper reach scene's goal marker sits there."""
    gripper, suction = load_model(arm.gripper_reach), load_model(arm.reach)
    poses = []
    for model in (gripper, suction):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
        mujoco.mj_kinematics(model, data)
        tcp = name_to_id(model, "site", "tcp")
        poses.append((data.site_xpos[tcp].copy(), data.site_xmat[tcp].reshape(3, 3).copy(), data))
    np.testing.assert_allclose(poses[0][1], poses[1][1], atol=1e-12)
    np.testing.assert_allclose(poses[0][1], [[0, 1, 0], [1, 0, 0], [0, 0, -1]], atol=1e-12)
    np.testing.assert_allclose(poses[0][0], arm.home_tcp, atol=1e-4)
    np.testing.assert_allclose(
        poses[0][0], poses[1][0] - [0, 0, panda.HAND_TCP_OFFSET - arm.facts.TCP_OFFSET], atol=1e-12
    )
    data = poses[0][2]
    home_q = getattr(arm.facts, "GRIPPER_HOME_Q", arm.facts.HOME_Q)  # the Panda's joint 7 undoes its yaw
    np.testing.assert_allclose(data.qpos[: len(home_q)], home_q)
    np.testing.assert_allclose(finger_q(gripper, data), (panda.FINGER_TRAVEL, panda.FINGER_TRAVEL))  # open


def test_the_panda_gripper_reach_goal_marker_is_at_the_home_tcp():
    model = load_model("panda_gripper_reach")
    np.testing.assert_allclose(
        model.body_pos[name_to_id(model, "body", "target")], panda.GRIPPER_HOME_TCP, atol=1e-4
    )
    np.testing.assert_allclose(
        panda.GRIPPER_HOME_TCP, panda.HOME_TCP - [0, 0, panda.HAND_TCP_OFFSET - panda.TCP_OFFSET]
    )


def test_robot_entry_names_the_gripper_servo(arm):
    robot = arm.robot
    model = robot.load_model()
    assert robot.suction is None
    a = name_to_id(model, "actuator", robot.gripper)
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
    for scene in (arm.gripper_reach, arm.grasp_scene):
        robot.validate(load_model(scene))


@pytest.mark.parametrize(("start", "command"), [(panda.MAX_WIDTH, 0.0), (0.0, panda.MAX_WIDTH)])
def test_fingers_travel_together_to_their_range_ends(arm, start, command):
    """From one end of the servo's range to the other: each finger ends at 0 or 40 mm, the fingers'
    inner faces `command` apart (measured between the geoms), and the two move as one all the way."""
    model = load_model(arm.robot.model)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, name_to_id(model, "key", "home"))
    for j in panda.FINGER_JOINTS:
        data.qpos[model.jnt_qposadr[name_to_id(model, "joint", j)]] = start / 2
    gripper = name_to_id(model, "actuator", arm.robot.gripper)
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


def test_closed_fingers_squeeze_the_object_with_the_rated_grasp_force(grasped):
    model, data, arm = grasped
    gripper = name_to_id(model, "actuator", arm.robot.gripper)
    assert data.actuator_force[gripper] == pytest.approx(-panda.GRASP_FORCE)  # saturated: 70 N per finger
    left, right = finger_box_forces(model, data, arm.obj)
    assert left == pytest.approx(panda.GRASP_FORCE, rel=0.01)
    assert right == pytest.approx(panda.GRASP_FORCE, rel=0.01)
    width = sum(finger_q(model, data))
    assert 2 * arm.obj_half - 1e-3 < width < 2 * arm.obj_half  # the contacts are stiff: < 0.5 mm per finger
    centred = tcp_in_hand_frame(model, data, arm.obj) - [0, 0, arm.grasp_height]  # the TCP's z: down
    np.testing.assert_allclose(centred, 0.0, atol=1e-3)  # centred by the coupling


def test_oppose_of_the_grasped_object_is_near_zero(grasped):
    """The coupled fingers centre the object they squeeze: RAI's opposition is below 0.1 mm."""
    model, data, arm = grasped
    spec = f"oppose(finger_left, finger_right, {arm.obj})"
    y = parse_spec(spec, model)(model, data).y
    assert np.linalg.norm(y) < 1e-4
    shifted = copy.copy(data)  # the same grasp with the object 2 mm towards finger_left: y = -4 mm there
    R = data.site_xmat[name_to_id(model, "site", "tcp")].reshape(3, 3)
    adr = model.jnt_qposadr[name_to_id(model, "joint", arm.obj)]
    shifted.qpos[adr : adr + 3] += 0.002 * R[:, 1]
    mujoco.mj_kinematics(model, shifted)
    mujoco.mj_comPos(model, shifted)
    y_shifted = parse_spec(spec, model)(model, shifted).y
    np.testing.assert_allclose(y_shifted - y, -0.004 * R[:, 1], atol=1e-5)


def test_a_width_target_inside_the_object_squeezes_below_the_rating(grasped):
    """3 mm inside the object the servo's force is below its limit, and the fingers press with that force."""
    model, data, arm = grasped
    data = copy.copy(data)
    gripper = name_to_id(model, "actuator", arm.robot.gripper)
    data.ctrl[gripper] = 2 * arm.obj_half - 0.003
    steps(model, data, 0.5)
    force = -data.actuator_force[gripper]
    assert 0.2 * panda.GRASP_FORCE < force < 0.8 * panda.GRASP_FORCE
    left, right = finger_box_forces(model, data, arm.obj)
    assert left == pytest.approx(force, rel=0.01) and right == pytest.approx(force, rel=0.01)


def test_the_lifted_object_is_held_against_gravity(grasped):
    model, data, arm = grasped
    data = copy.copy(data)
    obj = name_to_id(model, "body", arm.obj)
    z0, in_hand = data.xpos[obj][2], tcp_in_hand_frame(model, data, arm.obj)
    tcp = data.site_xpos[name_to_id(model, "site", "tcp")].copy()
    move_smoothly(model, data, arm_for_tcp(model, data, tcp + [0, 0, 0.15], arm.robot), 1.5)
    lifted = tcp_in_hand_frame(model, data, arm.obj)
    assert data.xpos[obj][2] - z0 == pytest.approx(0.15, abs=1e-3)
    assert np.linalg.norm(lifted - in_hand) < 5e-4  # no slip in the lift
    assert not any(
        {model.geom(g).name for g in data.contact.geom[i]} & {"table"} for i in range(data.ncon)
    )  # in the air
    steps(model, data, 2.0)
    assert (
        np.linalg.norm(tcp_in_hand_frame(model, data, arm.obj) - lifted) < 1e-4
    )  # nor in two seconds of holding


def test_gravity_compensation_with_the_hand_fits_in_the_torque_limits(arm, rng):
    model = load_model(arm.robot.model)
    data = mujoco.MjData(model)
    limits = arm.facts.JOINT_LIMITS
    n = len(limits)
    for q in rng.uniform(limits[:, 0], limits[:, 1], (200, n)):
        data.qpos[:n] = q
        mujoco.mj_forward(model, data)
        assert np.all(np.abs(data.qfrc_gravcomp[:n]) < 0.7 * arm.facts.MAX_JOINT_TORQUES)
