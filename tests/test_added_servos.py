"""The servos tsrl adds to a model without any (tsrl.servos, tsrl.robot_model), and the settling target
(tsrl.settling) on the built-in arms and on added-servo arms: gains against the inertia computed by
hand, the step response against the critically damped solution, the stability bound against the
simulation, gravity compensation, torque motors, unlimited hinges, pinning constraints, bad input."""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model, panda, ur5e
from tsrl.exceptions import InvalidConfig, SpecError
from tsrl.robot_model import RobotNotice, prepare_spec
from tsrl.robots import HOME_KEY, Robot
from tsrl.servos import (
    DEFAULT_BANDWIDTH_HZ,
    DEFAULT_HINGE_RANGE,
    add_servos,
    max_stable_bandwidth,
    servo_gains,
    servo_name,
    step_map_radius,
)
from tsrl.settling import CONTROL_DT, PERIODS, STEP, TOLERANCE, settle
from tsrl.taskmaps import parse_spec

#: One hinge about y; the link's centre of mass 0.3 m along x: M = I_yy + m L^2 + armature, by hand.
PENDULUM = """<mujoco>
  <compiler angle="radian"/>
  <option timestep="{dt}" gravity="0 0 {g}"/>
  <worldbody>
    <body name="link">
      <joint name="hinge" axis="0 1 0" range="-3 3" damping="0.5" armature="0.05"/>
      <inertial pos="0.3 0 0" mass="2" diaginertia="0.01 0.02 0.03"/>
      <site name="tip" pos="0.6 0 0"/>
    </body>
  </worldbody>
</mujoco>"""
PENDULUM_INERTIA = 0.02 + 2 * 0.3**2 + 0.05

#: A 3-joint arm with no actuators and no keyframe, as many models come.
BARE_ARM = """<mujoco model="arm3">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="base" pos="0 0 0.1">
      <joint name="yaw" axis="0 0 1" range="-3 3" damping="2" armature="0.1"/>
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="upper" pos="0 0 0.05">
        <joint name="shoulder" axis="0 1 0" range="-2 2" damping="2" armature="0.1"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1"/>
        <body name="fore" pos="0.4 0 0">
          <joint name="elbow" axis="0 1 0" {elbow} damping="2" armature="0.1"/>
          <geom type="capsule" fromto="0 0 0 0.35 0 0" size="0.025" mass="0.5"/>
          <site name="tool" pos="0.35 0 0"/>
        </body>
      </body>
      <body name="side" pos="0 0.2 0">
        <joint name="side" axis="0 1 0" range="-1 1"/>
        <geom type="sphere" size="0.02" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  {extra}
</mujoco>"""
JOINTS = ("yaw", "shoulder", "elbow")
HOME = (0.0, -0.5, 1.0)


def bare_arm(elbow: str = 'range="-2.5 2.5"', extra: str = "") -> mujoco.MjSpec:
    return mujoco.MjSpec.from_string(BARE_ARM.format(elbow=elbow, extra=extra))


def arm_robot(**fields) -> Robot:
    return Robot(
        **({"name": "arm3", "model": "arm.xml", "joints": JOINTS, "tcp": "tool", "home": HOME} | fields)
    )


def prepared(spec: mujoco.MjSpec, robot: Robot | None = None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RobotNotice)
        arm = prepare_spec(spec, robot or arm_robot(), "arm.toml")
    return spec.compile(), arm


# -- gains, response, stability ---------------------------------------------------------------------
def test_gains_come_from_the_joint_inertia_at_home_and_are_critically_damped():
    model = mujoco.MjModel.from_xml_string(PENDULUM.format(dt=0.002, g=0))
    (gains,) = servo_gains(model, ("hinge",), np.zeros(1), 12.0, [(-3.0, 3.0)])
    w = 2 * math.pi * 12.0
    assert gains.inertia == pytest.approx(PENDULUM_INERTIA, rel=1e-12)
    assert gains.kp == pytest.approx(PENDULUM_INERTIA * w**2, rel=1e-12)
    assert gains.kv == pytest.approx(2 * PENDULUM_INERTIA * w - 0.5, rel=1e-12)  # + the joint's 0.5


def test_an_added_servo_follows_the_critically_damped_step_response():
    """e(t) = e0 (1 + w t) exp(-w t) for the joint alone (no gravity), to the integrator's accuracy."""
    spec = mujoco.MjSpec.from_string(PENDULUM.format(dt=0.0002, g=0))
    model = spec.compile()
    gains = servo_gains(model, ("hinge",), np.zeros(1), 10.0, [(-3.0, 3.0)])
    add_servos(spec, gains)
    model = spec.compile()
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    data = mujoco.MjData(model)
    data.ctrl[0] = 0.1
    w, t, errors = 2 * math.pi * 10.0, [], []
    for _ in range(1000):  # 0.2 s
        mujoco.mj_step(model, data)
        t.append(data.time)
        errors.append(0.1 - data.qpos[0])
    expected = 0.1 * (1 + w * np.array(t)) * np.exp(-w * np.array(t))
    np.testing.assert_allclose(errors, expected, atol=2e-3 * 0.1)
    assert min(errors) > -1e-9  # critically damped: no overshoot


@pytest.mark.parametrize("factor, stable", [(0.97, True), (1.05, False)])
def test_the_stability_bound_is_where_the_simulation_blows_up(factor, stable):
    spec = mujoco.MjSpec.from_string(PENDULUM.format(dt=0.002, g=0))
    model = spec.compile()
    top = max_stable_bandwidth(model, ("hinge",), np.zeros(1), [(-3.0, 3.0)])
    assert 100 < top < 1000  # w dt of the order of 2 + 2 sqrt(2) for one joint
    gains = servo_gains(model, ("hinge",), np.zeros(1), factor * top, [(-3.0, 3.0)])
    assert (step_map_radius(model, ("hinge",), np.zeros(1), gains) < 1) == stable
    add_servos(spec, gains)
    model = spec.compile()
    data = mujoco.MjData(model)
    data.ctrl[0] = 0.01
    mujoco.mj_step(model, data, nstep=2000)
    blew_up = data.warning.number.sum() > 0 or not abs(data.qpos[0] - 0.01) < 1e-6
    assert blew_up != stable


# -- the settling target ----------------------------------------------------------------------------
@pytest.mark.parametrize("scene, arm", [("reach", ur5e), ("panda_reach", panda)], ids=["ur5e", "panda"])
def test_the_built_in_arms_meet_the_settling_target(scene, arm):
    model = load_model(scene)
    result = settle(model, arm.JOINT_NAMES, "tcp", np.array(arm.HOME_Q), model.key(arm.HOME_KEY).id)
    assert result.ok, result.summary()
    assert len(result.responses) == 6 and all(r.warnings == 0 for r in result.responses)


def test_an_added_servo_arm_meets_the_settling_target():
    model, arm = prepared(bare_arm())
    assert arm.servos == tuple(servo_name(j) for j in JOINTS) and arm.bandwidth_hz == DEFAULT_BANDWIDTH_HZ
    result = settle(model, JOINTS, "tool", np.array(HOME), model.key(HOME_KEY).id)
    assert result.ok, result.summary()


def test_settling_measures_what_it_says():
    """Servos too soft for the target miss it; the reported error is the TCP's distance at 0.12 s."""
    model, _ = prepared(bare_arm(), arm_robot(servo_bandwidth=2.0))
    result = settle(model, JOINTS, "tool", np.array(HOME), model.key(HOME_KEY).id)
    assert not result.ok and "misses" in result.summary()
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(HOME_KEY).id)
    mujoco.mj_forward(model, data)
    start = data.site("tool").xpos.copy()
    first = result.responses[0]  # +x
    assert first.direction == "+x" and first.settled_error > TOLERANCE
    # the servos get the IK's joint targets: replay them and compare the distance at the end of period 3
    from tsrl.ik import DlsSolver, IKOptions
    from tsrl.taskmaps import Position

    solver = DlsSolver(model, Position(model, "tool"), JOINTS, IKOptions(tol=1e-6, restarts=0))
    goal = start + [STEP, 0, 0]
    ik_data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, ik_data, model.key(HOME_KEY).id)
    q = solver.solve(ik_data, goal).q
    mujoco.mj_resetDataKeyframe(model, data, model.key(HOME_KEY).id)
    data.ctrl[:3] = q
    mujoco.mj_step(model, data, nstep=PERIODS * round(CONTROL_DT / model.opt.timestep))
    assert np.linalg.norm(data.site("tool").xpos - goal) == pytest.approx(first.settled_error, rel=1e-6)


# -- what tsrl adds ---------------------------------------------------------------------------------
def test_gravity_compensation_holds_home_and_its_absence_sags():
    held, _ = prepared(bare_arm())
    sagging, arm = prepared(bare_arm(), arm_robot(gravity_compensation=False))
    assert not arm.gravity_compensation
    for model, moved in ((held, False), (sagging, True)):
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key(HOME_KEY).id)
        mujoco.mj_step(model, data, nstep=500)
        assert (np.abs(data.qpos[:3] - HOME).max() > 1e-4) == moved
    gravcomp = {held.body(b).name: held.body_gravcomp[b] for b in range(held.nbody)}
    assert gravcomp == {"world": 0, "base": 1, "upper": 1, "fore": 1, "side": 1}  # what the joints move
    assert held.jnt_actgravcomp[[held.joint(j).id for j in JOINTS]].all()


def test_the_base_is_the_robot_files_or_what_the_first_joint_hangs_from():
    assert prepared(bare_arm())[1].base == "world"
    assert prepared(bare_arm(), arm_robot(base="base"))[1].base == "base"
    assert prepared(bare_arm(), arm_robot(joints=("shoulder", "elbow"), home=(-0.5, 1.0)))[1].base == "base"


def test_the_home_keyframe_holds_the_joint_values_and_their_servo_targets():
    model, _ = prepared(bare_arm())
    key = model.key(HOME_KEY).id
    np.testing.assert_array_equal(model.key_qpos[key][:3], HOME)
    np.testing.assert_array_equal(model.key_ctrl[key], HOME)
    np.testing.assert_array_equal(arm_robot().bind(model).ctrl, slice(0, 3))


def test_torque_motors_stay_at_zero_and_are_reported_once():
    motors = '<actuator><motor name="m_yaw" joint="yaw"/><motor name="m_elbow" joint="elbow"/></actuator>'
    spec = bare_arm(extra=motors)
    with pytest.warns(RobotNotice) as record:
        arm = prepare_spec(spec, arm_robot(), "arm.toml")
    assert len(record) == 1
    assert str(record[0].message) == (
        "arm.toml: actuators m_elbow, m_yaw on the controlled joints are not position servos; "
        "tsrl leaves them at zero and adds a position servo per joint"
    )
    model = spec.compile()
    assert model.nu == 5 and arm.servos == tuple(servo_name(j) for j in JOINTS)
    np.testing.assert_array_equal(model.key_ctrl[model.key(HOME_KEY).id][:2], [0, 0])


def test_an_unlimited_hinge_gets_the_default_range_on_its_servo_and_jointlimits_refuses_it():
    spec = bare_arm(elbow="")
    with pytest.warns(RobotNotice, match=r"arm.toml: hinge joints elbow have no range; .*\+-2 pi"):
        prepare_spec(spec, arm_robot(), "arm.toml")
    model = spec.compile()
    np.testing.assert_array_equal(model.actuator(servo_name("elbow")).ctrlrange, DEFAULT_HINGE_RANGE)
    assert not model.jnt_limited[model.joint("elbow").id]
    with pytest.raises(SpecError, match="jointLimits needs joints with limits; elbow have none"):
        parse_spec("jointLimits", model, joints=JOINTS)


def test_a_model_with_its_own_servos_is_left_as_it_is():
    servos = "".join(f'<position name="p_{j}" joint="{j}" kp="100"/>' for j in JOINTS)
    spec = bare_arm(extra=f"<actuator>{servos}</actuator>")
    before = spec.to_xml()
    _, arm = prepared(spec, arm_robot(home=None))
    assert arm.servos == tuple(f"p_{j}" for j in JOINTS) and arm.added == () and not arm.gravity_compensation
    assert spec.to_xml() == before


def test_a_weld_on_the_arm_is_an_error_unless_dropped():
    weld = '<worldbody><body name="holder" mocap="true"/></worldbody><equality><weld body1="holder" body2="fore"/></equality>'
    spec = bare_arm(extra=weld)
    before = spec.to_xml()
    with pytest.raises(InvalidConfig) as err:
        prepare_spec(spec, arm_robot(), "arm.toml")
    assert str(err.value) == (
        "arm.toml: weld (unnamed) between holder and fore acts on the controlled joints and pins the arm; "
        'accepted: drop_equalities = ["holder"] (removes it) or a model without it'
    )
    assert spec.to_xml() == before  # nothing half-built
    model, arm = prepared(spec, arm_robot(drop_equalities=("holder",)))
    assert model.neq == 0 and arm.dropped == ("weld (unnamed) between holder and fore",)


def test_a_constraint_off_the_arm_is_kept():
    """A joint coupling on a joint the arm does not move (side) does not pin the arm."""
    coupling = '<equality><joint name="lock" joint1="side"/></equality>'
    model, _ = prepared(bare_arm(extra=coupling))
    assert model.neq == 1


# -- bad input: one line naming the robot file, the key and what is accepted; nothing built --------
BAD = [
    (
        {"joints": ("yaw", "side")},
        (
            "arm.toml: joints: 'side' does not move the TCP 'tool'; accepted: joints on the chain from the "
            "base to the TCP, base to tip: yaw, shoulder, elbow"
        ),
    ),
    (
        {"joints": ("shoulder", "yaw", "elbow")},
        (
            "arm.toml: joints: 'yaw' comes after a joint below it; accepted: joints on the chain from the "
            "base to the TCP, base to tip: yaw, shoulder, elbow"
        ),
    ),
    ({"tcp": "gripper"}, "arm.toml: tcp: unknown frame 'gripper'; the model's frames: base, fore,"),
    ({"home": "rest"}, "arm.toml: home: unknown keyframe 'rest'; the model's keyframes: "),
    (
        {"home": (0.0, -0.5, 3.0)},
        "arm.toml: home: elbow = 3 outside [-2.5, 2.5]; accepted: values within the joints' ranges",
    ),
    (
        {"servo_bandwidth": 1000.0},
        "arm.toml: servo_bandwidth = 1000 Hz: the timestep 0.002 s cannot hold it",
    ),
    ({"servo_bandwidth": -1.0}, "arm.toml: servo_bandwidth = -1.0; accepted: a number of Hz > 0"),
    (
        {"drop_equalities": ("holder",)},
        (
            "arm.toml: drop_equalities: no equality constraint is named 'holder' or connects it; accepted: "
            "a constraint's name or a body/joint it connects (the model's: none)"
        ),
    ),
    ({"suction": "cup"}, "arm.toml: suction: unknown actuator 'cup'; the model's actuators: "),
    ({"base": "pedestal"}, "arm.toml: base: unknown body 'pedestal'; the model's bodys: base, fore, side,"),
]


@pytest.mark.parametrize("fields, message", BAD, ids=[f"{next(iter(f))}" for f, _ in BAD])
def test_bad_robot_settings_are_one_line_and_build_nothing(fields, message):
    spec = bare_arm()
    before = spec.to_xml()
    with pytest.raises(InvalidConfig) as err:
        prepare_spec(spec, arm_robot(**fields), "arm.toml")
    assert str(err.value).startswith(message) and "\n" not in str(err.value)
    assert spec.to_xml() == before


def test_servos_on_some_joints_but_not_all_are_an_error():
    spec = bare_arm(extra='<actuator><position name="p_yaw" joint="yaw" kp="100"/></actuator>')
    with pytest.raises(InvalidConfig) as err:
        prepare_spec(spec, arm_robot(), "arm.toml")
    assert str(err.value) == (
        "arm.toml: actuators: the model has position servos on yaw but not on shoulder, elbow; "
        "accepted: a servo on every controlled joint, or on none (tsrl adds them)"
    )
    with pytest.raises(
        InvalidConfig, match="arm.toml: actuators: 'p_yaw' is not a position servo of joint 'shoulder'"
    ):
        robot = arm_robot(joints=("yaw", "shoulder"), actuators=("p_yaw", "p_yaw"), home=(0.0, -0.5))
        prepare_spec(spec, robot, "arm.toml")


def test_a_bandwidth_for_a_model_with_its_own_servos_is_an_error():
    servos = "".join(f'<position name="p_{j}" joint="{j}" kp="100"/>' for j in JOINTS)
    with pytest.raises(InvalidConfig, match=r"arm.toml: servo_bandwidth = 20: the model has its own servos"):
        prepare_spec(
            bare_arm(extra=f"<actuator>{servos}</actuator>"), arm_robot(servo_bandwidth=20.0), "arm.toml"
        )


URDF = """<robot name="slider">
  <link name="base"/>
  <link name="l1"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><origin xyz="0.1 0 0"/><mass value="0.5"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="continuous"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0.2 0 0"/>
    <axis xyz="1 0 0"/>{limit}</joint>
</robot>"""


def test_a_urdf_without_limits_on_a_slide_is_an_error_and_with_them_gets_servos(tmp_path):
    path = tmp_path / "slider.urdf"
    robot = Robot(name="slider", model=str(path), joints=("j1", "j2"), tcp="l2")
    path.write_text(URDF.format(limit=""))
    with pytest.raises(InvalidConfig) as err:
        prepare_spec(mujoco.MjSpec.from_file(str(path)), robot, "slider.toml")
    assert str(err.value) == (
        "slider.toml: joints: slide joint 'j2' has no range, so no servo range; accepted: slide joints "
        "with limits (MJCF range, URDF <limit lower upper>)"
    )
    path.write_text(URDF.format(limit='<limit lower="-0.1" upper="0.1" effort="10" velocity="1"/>'))
    spec = mujoco.MjSpec.from_file(str(path))
    with pytest.warns(RobotNotice, match="hinge joints j1 have no range"):
        arm = prepare_spec(spec, robot, "slider.toml")
    model = spec.compile()
    assert model.nu == 2 and arm.servos == (servo_name("j1"), servo_name("j2"))
    np.testing.assert_array_equal(model.actuator(servo_name("j2")).ctrlrange, [-0.1, 0.1])


def test_unnamed_servos_of_the_model_get_names_so_that_the_robot_binds_them():
    servos = "".join(f'<position joint="{j}" kp="100"/>' for j in JOINTS)
    model, arm = prepared(bare_arm(extra=f"<actuator>{servos}</actuator>"), arm_robot())
    assert arm.added == () and arm.servos == tuple(servo_name(j) for j in JOINTS)
    assert [model.actuator(a).name for a in range(model.nu)] == list(arm.servos)
    np.testing.assert_array_equal(arm_robot().bind(model).ctrl, slice(0, 3))
