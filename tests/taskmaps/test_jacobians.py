"""Every registered map's Jacobian against central finite differences; velocity maps against
finite differences in time. Parameterised over the parser's registry, so a new map is tested."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.assets import load_model
from tsrl.kinematics import forward_kinematics, random_configurations
from tsrl.taskmaps import known_maps, parse_spec

from .conftest import CONTACT_MAPS, example_spec, finite_difference_jacobian, pressed_into_table, set_qpos

#: Absolute tolerance near the pressed pose: MuJoCo's convex collision (cylinder against box) stops
#: once the depth is within `ccd_tolerance` (1e-6), an error that changes with q, so central
#: differences of the value itself are off by up to ~4e-6 (test_distance_jacobian_is_exact_with_a_
#: tight_collision_tolerance shows the Jacobian exact once the value is). The witness points are
#: only accurate to ~0.2 mm along the surface; the maps use the geoms' support points instead
#: (with the witness points, J was off by up to 3e-4).
CONTACT_ATOL = 1e-5


def _configurations(
    name: str, model: mujoco.MjModel, rng: np.random.Generator, pressed_q: np.ndarray
) -> tuple[np.ndarray, float]:
    """Configurations at which to test the map `name`, and the tolerance there."""
    if name in CONTACT_MAPS:  # near the pressed pose, where the contact is smooth
        return pressed_q + rng.uniform(-0.01, 0.01, size=(3, 6)), CONTACT_ATOL
    return random_configurations(model, rng, 4), 1e-6


@pytest.mark.parametrize("name", [n for n in known_maps() if n != "velocity"])
def test_jacobian_matches_finite_differences(name, ur5e, rng, pressed_q):
    model, data = ur5e
    task_map = parse_spec(example_spec(name), model)
    qs, atol = _configurations(name, model, rng, pressed_q)
    for q in qs:
        forward_kinematics(model, data, q)
        J = task_map(model, data).J
        np.testing.assert_allclose(J, finite_difference_jacobian(task_map, model, data), atol=atol)


def test_distance_jacobian_is_exact_with_analytic_witness_points(ur5e, rng):
    model, data = ur5e
    task_map = parse_spec("distance(forearm_tube, table)", model)  # capsule-box: closed-form points
    signs = set()
    for q in random_configurations(model, rng, 30):
        forward_kinematics(model, data, q)
        y, J = task_map(model, data)
        if abs(y[0]) < 1e-3:  # too close to touching for central differences
            continue
        signs.add(bool(y[0] > 0))
        np.testing.assert_allclose(J, finite_difference_jacobian(task_map, model, data), atol=1e-6)
    assert signs == {True, False}  # apart and penetrating both checked


@pytest.mark.parametrize("depth", [0.0005, 0.004, 0.009])
@pytest.mark.parametrize("tilt", [0.05, 0.3])
def test_distance_jacobian_under_penetration(reach_model, depth, tilt):
    """The suction cup (a cylinder) pressed into the table (a box), deepest at one rim point."""
    model, data = reach_model, mujoco.MjData(reach_model)
    task_map = parse_spec("distance(suction_cup, table)", model)
    forward_kinematics(model, data, pressed_into_table(model, depth, tilt))
    y, J = task_map(model, data)
    cup_radius = model.geom_size[model.geom("suction_cup").id][0]
    assert y[0] == pytest.approx(-depth - cup_radius * np.sin(tilt), abs=1e-5)  # the rim is deepest
    np.testing.assert_allclose(J, finite_difference_jacobian(task_map, model, data), atol=CONTACT_ATOL)


def test_distance_jacobian_is_exact_with_a_tight_collision_tolerance(rng):
    """With MuJoCo's depth exact (ccd_tolerance 1e-12), J equals central differences to 1e-8."""
    model = load_model("reach")
    model.opt.ccd_tolerance, model.opt.ccd_iterations = 1e-12, 200
    data = mujoco.MjData(model)
    task_map = parse_spec("distance(suction_cup, table), distance(forearm_tube, table)", model)
    for depth, tilt in [(0.002, 0.1), (0.006, 0.4), (-0.008, 0.2)]:  # the last one apart
        forward_kinematics(model, data, pressed_into_table(model, depth, tilt))
        assert np.sign(task_map(model, data).y[0]) == -np.sign(depth)
        J = task_map(model, data).J
        np.testing.assert_allclose(J, finite_difference_jacobian(task_map, model, data), atol=1e-8)


def test_contact_maps_are_tested_in_contact(ur5e, pressed_q):
    model, data = ur5e
    forward_kinematics(model, data, pressed_q)
    y = parse_spec("distance(suction_cup, table), accumulatedCollisions", model)(model, data).y
    assert y[0] < -1e-3 and y[1] > 1e-3


@pytest.mark.parametrize(
    "spec", ["scalarProductZZ(world, tcp)", "positionRel(tcp, world)", "quaternion(flange)"]
)
def test_world_and_flange_frames_match_finite_differences(spec, ur5e, rng):
    model, data = ur5e
    task_map = parse_spec(spec, model)
    for q in random_configurations(model, rng, 3):
        forward_kinematics(model, data, q)
        np.testing.assert_allclose(
            task_map(model, data).J, finite_difference_jacobian(task_map, model, data), atol=1e-6
        )


@pytest.mark.parametrize("inner", [n for n in known_maps() if n != "velocity"])
def test_velocity_value_matches_finite_differences_in_time(inner, ur5e, rng, pressed_q):
    model, data = ur5e
    velocity = parse_spec(f"velocity({example_spec(inner)})", model)
    position = parse_spec(example_spec(inner), model)
    dt = 1e-6
    qs, atol = _configurations(inner, model, rng, pressed_q)
    for q in qs:
        forward_kinematics(model, data, q)
        data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
        y_dot = velocity(model, data).y
        q0 = data.qpos.copy()
        q_plus, q_minus = q0.copy(), q0.copy()
        mujoco.mj_integratePos(model, q_plus, data.qvel, dt)
        mujoco.mj_integratePos(model, q_minus, data.qvel, -dt)
        set_qpos(model, data, q_plus)
        y_plus = position(model, data).y
        set_qpos(model, data, q_minus)
        y_minus = position(model, data).y
        np.testing.assert_allclose(y_dot, position.difference(y_plus, y_minus) / (2 * dt), atol=atol)


@pytest.mark.parametrize("inner", ["position(tcp)", "quaternionDiff(tcp, upper_arm_link)", "jointLimits"])
def test_velocity_jacobian_is_the_inner_jacobian_d_ydot_d_qdot(inner, ur5e, rng):
    model, data = ur5e
    velocity, inner_map = parse_spec(f"velocity({inner})", model), parse_spec(inner, model)
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    J = velocity(model, data).J
    np.testing.assert_array_equal(J, inner_map(model, data).J)
    eps = 1e-6  # y_dot is linear in q_dot: central differences in qvel are exact up to rounding
    qvel = data.qvel.copy()
    for k in range(model.nv):
        data.qvel[:] = qvel
        data.qvel[k] += eps
        y_plus = velocity(model, data).y
        data.qvel[k] -= 2 * eps
        y_minus = velocity(model, data).y
        np.testing.assert_allclose(J[:, k], (y_plus - y_minus) / (2 * eps), atol=1e-7)
