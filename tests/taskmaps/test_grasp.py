"""oppose (RAI's F_GraspOppose) and gripperWidth: values against independent computations (MuJoCo's
own distance and transmission length, hand-computed symmetric grasps), Jacobians against central
finite differences with the fingers apart from and pressing into the object, bad input, relabelling,
and, where the `robotic` package (RAI's Python bindings) imports, RAI itself."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
import scipy.optimize

from tsrl.assets import load_model, panda
from tsrl.exceptions import NotRelabelable, SpecError, UnknownName
from tsrl.kinematics import name_to_id
from tsrl.taskmaps import parse_spec
from tsrl.taskmaps.cores import Core, core_of, core_pair
from tsrl.taskmaps.relabel import FrameMove, relabelled

from .conftest import set_qpos

#: Free bodies carrying every core kind: boxes, capsules (segments) and a sphere (a point).
SHAPES = """
<mujoco>
  <option ccd_tolerance="1e-13" ccd_iterations="1000"/>
  <worldbody>
    <body name="a"><freejoint/><geom name="box_a" type="box" size="0.03 0.02 0.01"/></body>
    <body name="b"><freejoint/><geom name="capsule_b" type="capsule" size="0.01 0.03"/></body>
    <body name="c"><freejoint/><geom name="sphere_c" type="sphere" size="0.02"/></body>
    <body name="o"><freejoint/><geom name="box_o" type="box" size="0.04 0.03 0.02"/></body>
    <body name="p"><freejoint/><geom name="capsule_p" type="capsule" size="0.015 0.04"/>
      <site name="on_p"/></body>
    <body name="peg"><freejoint/><geom name="cylinder_peg" type="cylinder" size="0.01 0.03"/></body>
  </worldbody>
</mujoco>
"""
#: oppose over every pair of core kinds (finger against object), with boxes on both sides.
SHAPE_SPECS = (
    "oppose(box_a, capsule_b, box_o)",
    "oppose(sphere_c, box_a, box_o)",
    "oppose(capsule_b, sphere_c, capsule_p)",
    "oppose(box_a, sphere_c, capsule_p)",
    "oppose(box_o, capsule_p, sphere_c)",
)
EPS = 1e-6


@pytest.fixture(scope="module")
def shapes():
    model = mujoco.MjModel.from_xml_string(SHAPES)
    return model, mujoco.MjData(model)


@pytest.fixture(scope="module")
def gripper_scene():
    model = load_model("panda_gripper_pick_place")
    return model, mujoco.MjData(model)


def _geoms(spec: str) -> list[str]:
    return spec[spec.index("(") + 1 : -1].split(", ")


def _random_quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def _shapes_q(model, rng, spread: float = 0.06) -> np.ndarray:
    """Every free body at a random pose within `spread` of the origin: the shapes often overlap."""
    q = np.zeros(model.nq)
    for b in range(model.njnt):
        adr = model.jnt_qposadr[b]
        q[adr : adr + 3] = rng.uniform(-spread, spread, 3)
        q[adr + 3 : adr + 7] = _random_quat(rng)
    return q


def _feature(core: Core, p: np.ndarray) -> tuple[int, ...]:
    """Which vertex, edge or face of the core holds p: the signs of its clamped local coordinates."""
    if core.kind == "point":
        return ()
    if core.kind == "segment":
        half, t = np.linalg.norm(core.vertices[1] - core.c), (p - core.c) @ core.R[:, 2]
        return (int(np.sign(t)) if abs(t) >= half - 1e-10 else 0,)
    local = core.R.T @ (p - core.c)
    return tuple(int(np.sign(x)) if abs(x) >= s - 1e-10 else 0 for x, s in zip(local, core.s))


def _features(model, data, spec) -> tuple:
    """The feature pairs (and apart/intersecting) of both fingers against the object."""
    ids = [name_to_id(model, "geom", g) for g in _geoms(spec)]
    obj = core_of(model, data, ids[2])
    out = []
    for g in ids[:2]:
        finger = core_of(model, data, g)
        pair = core_pair(finger, obj)
        out.append((pair.apart, _feature(finger, pair.p_a), _feature(obj, pair.p_b)))
    return tuple(out)


def _dofs(model, spec) -> list[int]:
    """The dofs that move the bodies of the spec's three geoms."""
    bodies = {int(model.geom_bodyid[name_to_id(model, "geom", g)]) for g in _geoms(spec)}
    jac = np.zeros((3, model.nv))
    moved: set[int] = set()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    for body in bodies:
        mujoco.mj_jacBody(model, data, jac, None, body)
        moved |= set(np.flatnonzero(np.abs(jac).sum(axis=0) > 0).tolist())
        mujoco.mj_jacBody(model, data, None, jac, body)
        moved |= set(np.flatnonzero(np.abs(jac).sum(axis=0) > 0).tolist())
    return sorted(moved)


def _fd_if_smooth(task_map, model, data, spec) -> np.ndarray | None:
    """Central differences of y at data.qpos over the dofs that move the spec's geoms (zero columns
    elsewhere), or None where a finger's or the object's closest feature changes within the stencil
    (the map has no derivative there to compare with)."""
    q0, features = data.qpos.copy(), _features(model, data, spec)
    J = np.zeros((task_map.dim, model.nv))
    smooth = True
    for k in _dofs(model, spec):
        ys = []
        for sign in (1.0, -1.0):
            q = q0.copy()
            mujoco.mj_integratePos(model, q, np.eye(model.nv)[k], sign * EPS)
            set_qpos(model, data, q)
            ys.append(task_map(model, data).y)
            smooth &= _features(model, data, spec) == features
        J[:, k] = (ys[0] - ys[1]) / (2 * EPS)
    set_qpos(model, data, q0)
    return J if smooth else None


def _check_jacobians(spec, model, data, configurations) -> tuple[int, set[bool]]:
    """Asserts J == central differences at every configuration where the features persist; returns
    how many were compared and whether fingers were apart (True) / intersecting (False) among them."""
    task_map = parse_spec(spec, model)
    compared, seen = 0, set()
    for q in configurations:
        set_qpos(model, data, q)
        J = task_map(model, data).J
        J_fd = _fd_if_smooth(task_map, model, data, spec)
        if J_fd is None:
            continue
        np.testing.assert_allclose(J, J_fd, atol=1e-7, err_msg=spec)
        compared += 1
        seen |= {apart for apart, _, _ in _features(model, data, spec)}
    return compared, seen


# -- oppose: Jacobian ----------------------------------------------------------------------------------
@pytest.mark.parametrize("spec", SHAPE_SPECS)
def test_oppose_jacobian_matches_finite_differences_apart_and_penetrating(spec, shapes, rng):
    model, data = shapes
    n = 20
    compared, seen = _check_jacobians(spec, model, data, [_shapes_q(model, rng) for _ in range(n)])
    assert compared >= 0.95 * n  # a feature changes within 1e-6 rarely
    has_box = any("box" in g for g in _geoms(spec))
    assert seen == ({True, False} if has_box else {True})  # cores of points and segments never intersect


def _grasp_configurations(model, rng, n):
    """The gripper Panda at random arm poses, fingers open 0-40 mm each (not equal), and the box
    near the TCP, turned at random: fingers apart from it or pressing into it."""
    data = mujoco.MjData(model)
    tcp, box_adr = name_to_id(model, "site", "tcp"), model.jnt_qposadr[name_to_id(model, "joint", "box")]
    qs = []
    for _ in range(n):
        q = model.qpos0.copy()
        q[:7] = rng.uniform(panda.JOINT_LIMITS[:, 0], panda.JOINT_LIMITS[:, 1])
        q[7:9] = rng.uniform(0.0, panda.FINGER_TRAVEL, 2)
        set_qpos(model, data, q)
        R = data.site_xmat[tcp].reshape(3, 3)
        q[box_adr : box_adr + 3] = data.site_xpos[tcp] + R @ rng.uniform(-0.015, 0.015, 3)
        q[box_adr + 3 : box_adr + 7] = _random_quat(rng)
        qs.append(q)
    return qs


def test_oppose_jacobian_on_the_gripper_panda_apart_and_penetrating(gripper_scene, rng):
    model, data = gripper_scene
    spec, n = "oppose(finger_left, finger_right, box)", 15
    compared, seen = _check_jacobians(spec, model, data, _grasp_configurations(model, rng, n))
    assert compared >= 0.95 * n and seen == {True, False}


# -- oppose: value ---------------------------------------------------------------------------------------
#: Geoms with a radius around their core.
_ROUND = (int(mujoco.mjtGeom.mjGEOM_SPHERE), int(mujoco.mjtGeom.mjGEOM_CAPSULE))


def _mujoco_core_vector(model, data, finger: int, obj: int) -> np.ndarray:
    """RAI's pair vector with radii neglected, from MuJoCo's signed distance of the geoms themselves:
    the cores are the geoms shrunk by the sphere's or capsule's radius r, so D = -(d + r_f + r_o) n
    with n = (p_obj - p_f) / d the unit normal from the finger towards the object."""
    fromto = np.zeros(6)
    d = mujoco.mj_geomDistance(model, data, finger, obj, 10.0, fromto)
    n = (fromto[3:] - fromto[:3]) / d
    radius = [model.geom_size[g][0] if int(model.geom_type[g]) in _ROUND else 0.0 for g in (finger, obj)]
    return -(d + sum(radius)) * n


def _deepest_vector(finger: Core, obj: Core) -> np.ndarray:
    """The intersecting cores' vector w = h(n) n, n = argmin over unit n of the support function
    h(n) = h_finger(n) + h_obj(-n) of their Minkowski difference (its nearest facet to the origin),
    found by sampling directions and polishing with Nelder-Mead: no feature or axis list involved."""

    def h(x: np.ndarray) -> float:
        n = x / np.linalg.norm(x)
        return float(np.max(finger.vertices @ n) + np.max(-obj.vertices @ n))

    starts = np.random.default_rng(0).normal(size=(4000, 3))
    units = starts / np.linalg.norm(starts, axis=1, keepdims=True)
    values = np.max(units @ finger.vertices.T, axis=1) + np.max(-units @ obj.vertices.T, axis=1)
    best = min(
        (
            scipy.optimize.minimize(
                h, starts[i], method="Nelder-Mead", options={"xatol": 1e-13, "fatol": 1e-15, "maxiter": 4000}
            )
            for i in np.argsort(values)[:3]
        ),
        key=lambda r: r.fun,
    )
    n = best.x / np.linalg.norm(best.x)
    return best.fun * n


@pytest.mark.parametrize("spec", SHAPE_SPECS)
def test_oppose_is_the_sum_of_the_pair_vectors_measured_independently(spec, shapes, rng):
    """Apart: MuJoCo's signed distance of the geoms themselves (cores = geoms shrunk by the radius).
    Intersecting: the Minkowski difference's support function, minimised over directions. (MuJoCo's
    capsule-box collider takes the capsule's sphere nearest to the box as the penetration, not the
    shortest separating translation that RAI's cores use, so it is not the reference there.)"""
    model, data = shapes
    task_map = parse_spec(spec, model)
    a, b, obj = (name_to_id(model, "geom", g) for g in _geoms(spec))
    kinds = set()
    for _ in range(25):
        set_qpos(model, data, _shapes_q(model, rng))
        mujoco.mj_forward(model, data)  # geom poses for mj_geomDistance
        expected = np.zeros(3)
        for finger in (a, b):
            pair = core_pair(core_of(model, data, finger), core_of(model, data, obj))
            kinds.add(pair.apart)
            if pair.apart:
                expected += _mujoco_core_vector(model, data, finger, obj)
            else:
                expected += _deepest_vector(core_of(model, data, finger), core_of(model, data, obj))
        np.testing.assert_allclose(task_map(model, data).y, expected, atol=1e-8)
    assert True in kinds


def _hand_and_box(model, data, opening: float, shift: float, lift: float = 0.0):
    """The gripper Panda at home, each finger open by `opening`, the box at the TCP turned as the hand,
    moved by `shift` along the hand's y axis (towards finger_left) and `lift` along its z axis."""
    q = model.qpos0.copy()
    q[:7] = panda.GRIPPER_HOME_Q
    q[7:9] = opening
    set_qpos(model, data, q)
    tcp = name_to_id(model, "site", "tcp")
    R = data.site_xmat[tcp].reshape(3, 3)
    adr = model.jnt_qposadr[name_to_id(model, "joint", "box")]
    q[adr : adr + 3] = data.site_xpos[tcp] + R @ [0.0, shift, lift]
    mujoco.mju_mat2Quat(q[adr + 3 : adr + 7], R.ravel())
    set_qpos(model, data, q)
    return R


@pytest.mark.parametrize("opening", [0.03, 0.019], ids=["apart", "pressing"])
def test_oppose_is_zero_for_symmetric_fingers_and_minus_twice_the_offset_otherwise(opening, gripper_scene):
    """Fingers open `opening` each about a 4 cm box: gaps opening - 0.02 on both sides (negative when
    pressing in). D_left = (gap - shift) y_hand, D_right = -(gap + shift) y_hand, so y = -2 shift y_hand."""
    model, data = gripper_scene
    oppose = parse_spec("oppose(finger_left, finger_right, box)", model)
    _hand_and_box(model, data, opening, 0.0)
    np.testing.assert_allclose(oppose(model, data).y, 0.0, atol=1e-12)
    for shift in (0.004, -0.0007):
        R = _hand_and_box(model, data, opening, shift, lift=0.005)
        np.testing.assert_allclose(oppose(model, data).y, -2 * shift * R[:, 1], atol=1e-12)


# -- oppose: bad input, relabelling ------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("oppose(finger_left, finger_right, tcp)", "'tcp' is a site, not a geom"),
        ("oppose(finger_left, finger_right, hand)", "'hand' is a geom"),  # the housing geom: accepted
        ("oppose(finger_left, finger_right, link7)", "'link7' is a geom"),
        ("oppose(finger_left, finger_right, target)", "'target' is a site, not a geom"),
        ("oppose(finger_left, finger_right, cup)", "no geom 'cup'"),
        ("oppose(finger_left, finger_left, box)", "the same geom twice"),
    ],
)
def test_oppose_over_what_is_not_a_shape_is_one_line(spec, message, gripper_scene):
    model, _ = gripper_scene
    if "is a geom" in message:  # a geom of an accepted type builds
        name = message.split("'")[1]
        if int(model.geom_type[name_to_id(model, "geom", name)]) == int(mujoco.mjtGeom.mjGEOM_BOX):
            parse_spec(spec, model)
            return
        message = f"geom '{name}' is a "
    with pytest.raises(SpecError) as err:
        parse_spec(spec, model)
    text = str(err.value)
    assert message in text and spec in text and "box, capsule or sphere geoms" in text
    assert "\n" not in text


def test_oppose_over_a_cylinder_names_its_type(shapes):
    model, _ = shapes
    with pytest.raises(
        SpecError, match=r"oppose\(box_a, sphere_c, cylinder_peg\): geom 'cylinder_peg' is a cylinder"
    ):
        parse_spec("oppose(box_a, sphere_c, cylinder_peg)", model)
    with pytest.raises(SpecError, match=r"'on_p' is a site, not a geom \(a shape\)"):
        parse_spec("oppose(box_a, sphere_c, on_p)", model)
    with pytest.raises(SpecError, match=r"'p' is a body, not a geom"):
        parse_spec("oppose(box_a, sphere_c, p)", model)


def test_oppose_is_unchanged_by_the_goal_and_refuses_a_move_of_its_shapes(gripper_scene, rng):
    model, data = gripper_scene
    oppose = parse_spec(
        "oppose(finger_left, finger_right, box), velocity(oppose(finger_left, finger_right, box))", model
    )
    set_qpos(model, data, _grasp_configurations(model, rng, 1)[0])
    y = oppose(model, data).y
    q = np.array([1.0, 0, 0, 0])
    np.testing.assert_array_equal(relabelled(oppose, y, FrameMove("target", np.ones(3), q, q, True, {})), y)
    with pytest.raises(NotRelabelable, match=r"oppose\(finger_left, finger_right, box\)"):
        relabelled(oppose, y, FrameMove("box", np.ones(3), q, q, False, {}))


# -- gripperWidth ------------------------------------------------------------------------------------------
def test_gripper_width_is_the_servos_transmission_length_and_the_fingers_gap(gripper_scene, rng):
    model, data = gripper_scene
    width = parse_spec("gripperWidth(gripper)", model)
    gripper = name_to_id(model, "actuator", "gripper")
    faces = [name_to_id(model, "geom", g) for g in panda.FINGER_JOINTS]
    for q in _grasp_configurations(model, rng, 20):  # the fingers open unequally: no coupling assumed
        set_qpos(model, data, q)
        y, J = width(model, data)
        mujoco.mj_forward(model, data)  # MuJoCo's own transmission length
        assert y[0] == pytest.approx(data.actuator_length[gripper], abs=1e-15)
        assert y[0] == pytest.approx(q[7] + q[8], abs=1e-15)
        assert y[0] == pytest.approx(mujoco.mj_geomDistance(model, data, *faces, 1.0, None), abs=1e-9)
        expected = np.zeros(model.nv)
        expected[model.jnt_dofadr[name_to_id(model, "joint", "finger_left")]] = 1.0
        expected[model.jnt_dofadr[name_to_id(model, "joint", "finger_right")]] = 1.0
        np.testing.assert_array_equal(J[0], expected)


def test_gripper_width_jacobian_matches_finite_differences(gripper_scene, rng):
    from .conftest import finite_difference_jacobian

    model, data = gripper_scene
    width = parse_spec("gripperWidth(gripper)", model)
    for q in _grasp_configurations(model, rng, 5):
        set_qpos(model, data, q)
        np.testing.assert_allclose(
            width(model, data).J, finite_difference_jacobian(width, model, data), atol=1e-9
        )


def test_gripper_width_bad_actuators_are_one_line(reach_model):
    with pytest.raises(
        SpecError, match=r"gripperWidth\(suction\): actuator 'suction' has no joint or fixed-tendon"
    ):
        parse_spec("gripperWidth(suction)", reach_model)
    with pytest.raises(
        UnknownName,
        match="unknown actuator 'gripper' in spec 'gripperWidth\\(gripper\\)'; the model's actuators: elbow",
    ):
        parse_spec("gripperWidth(gripper)", reach_model)


def test_gripper_width_is_unchanged_by_any_frame_move(gripper_scene):
    model, _ = gripper_scene
    width = parse_spec("gripperWidth(gripper), velocity(gripperWidth(gripper))", model)
    y = np.array([0.03, 0.1])
    q = np.array([1.0, 0, 0, 0])
    for frame in ("target", "box", "hand"):
        np.testing.assert_array_equal(relabelled(width, y, FrameMove(frame, np.ones(3), q, q, True, {})), y)


# -- RAI itself ------------------------------------------------------------------------------------------
def _robotic():
    """RAI's Python bindings (`pip install robotic`; they need liblapack3 and a few GL libraries of the
    system), or a skip where they do not import."""
    try:
        import robotic  # optional: only this comparison needs it
    except (ImportError, OSError) as err:
        pytest.skip(f"RAI's `robotic` package does not import here: {err}")
    return robotic


def _rai_configuration(ry, model, data, geoms):
    """An RAI configuration with each geom as a frame of the same shape and world pose (RAI's box sizes
    are full lengths, ssBox radius 0; a capsule is [length, radius] along z as in MuJoCo)."""
    C = ry.Config()
    for name in geoms:
        g = name_to_id(model, "geom", name)
        frame, size = C.addFrame(name), model.geom_size[g]
        kind = int(model.geom_type[g])
        if kind == int(mujoco.mjtGeom.mjGEOM_BOX):
            frame.setShape(ry.ST.ssBox, [*(2 * size), 0.0])
        elif kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
            frame.setShape(ry.ST.capsule, [2 * size[1], size[0]])
        else:
            frame.setShape(ry.ST.sphere, [size[0]])
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, data.geom_xmat[g])
        frame.setPosition(data.geom_xpos[g].copy())
        frame.setQuaternion(quat)
    return C


@pytest.mark.parametrize("spec", SHAPE_SPECS)
def test_oppose_equals_rais_own_where_the_cores_are_apart(spec, shapes, rng):
    """RAI's FS.oppose in the same configuration. Where a finger's core intersects the object's, RAI
    (robotic 0.4.2) returns a zero pair vector; tsrl continues the vector through contact (the signed
    penetration), so those draws are left out here (tests above check them)."""
    ry = _robotic()
    model, data = shapes
    task_map, geoms = parse_spec(spec, model), _geoms(spec)
    compared = 0
    for _ in range(30):
        set_qpos(model, data, _shapes_q(model, rng))
        mujoco.mj_forward(model, data)
        if not all(apart for apart, _, _ in _features(model, data, spec)):
            continue
        y_rai, _ = _rai_configuration(ry, model, data, geoms).eval(ry.FS.oppose, geoms)
        np.testing.assert_allclose(task_map(model, data).y, y_rai, atol=1e-12)
        compared += 1
    assert compared >= 10
