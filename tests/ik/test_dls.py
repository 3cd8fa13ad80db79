"""DlsSolver on the real UR5e: the step formula, known solutions, behaviour, limits, bad input."""

from __future__ import annotations

from itertools import pairwise

import mujoco
import numpy as np
import pytest

from tsrl.assets.ur5e import HOME_Q, JOINT_LIMITS
from tsrl.envs import OBS_PRESETS
from tsrl.exceptions import InvalidConfig, UnknownName
from tsrl.ik import DlsSolver, IKOptions, IKResult
from tsrl.ik.dls import _dls, _Workspace
from tsrl.kinematics import forward_kinematics, random_configurations
from tsrl.taskmaps import parse_spec

from .conftest import ALIGNMENT, POSE, Recording, target_at, within_limits


def quaternion_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Rotation angle [rad] between unit quaternions a and b (either sign)."""
    return float(2.0 * np.arccos(min(1.0, abs(a @ b))))


def full_solve(model, data, task_map, target, *, joints=None, initial_value=None, **options) -> IKResult:
    """A full solve with the given options (the tests' shorthand)."""
    return DlsSolver(model, task_map, joints, IKOptions(**options)).solve(data, target, initial_value)


def dls_step(J: np.ndarray, e: np.ndarray, damping: float, d: np.ndarray | None = None) -> np.ndarray:
    """The solver's step formula on raw J (k, n), e (k,)."""
    return _dls(np.ascontiguousarray(J), np.ascontiguousarray(e), damping, d, _Workspace(min(J.shape)))


# The step formula itself


@pytest.mark.parametrize("k", [3, 6, 7])
def test_dls_step_is_the_damped_least_squares_formula(k, rng):
    J, e, lam = rng.normal(size=(k, 6)), rng.normal(size=k), 1e-2
    J0, e0 = J.copy(), e.copy()
    expected = J.T @ np.linalg.solve(J @ J.T + lam * np.eye(k), e)
    np.testing.assert_allclose(dls_step(J, e, lam), expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(J, J0)  # pure
    np.testing.assert_array_equal(e, e0)


def test_dls_step_null_space_term_is_the_projected_posture_step(rng):
    J, e, d, lam = rng.normal(size=(3, 6)), rng.normal(size=3), rng.normal(size=6), 1e-3
    pinv = J.T @ np.linalg.inv(J @ J.T + lam * np.eye(3))
    expected = pinv @ e + (np.eye(6) - pinv @ J) @ d
    np.testing.assert_allclose(dls_step(J, e, lam, d), expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    "spec", [POSE, ALIGNMENT, OBS_PRESETS["fs2"], "quaternion(tcp)", "quaternion(tcp), quaternion(flange)"]
)
def test_stack_difference_of_one_value_gives_the_parts_own_numbers(reach_model, spec, rng):
    """The stack's fast path for one value equals its parts' own rules, sign boundary included."""
    task_map = parse_spec(spec, reach_model, presets=OBS_PRESETS)
    pairs = [rng.normal(size=(2, task_map.dim)) for _ in range(50)]
    boundary = np.zeros((2, task_map.dim))
    boundary[0, ::4], boundary[1, 1::4] = 1.0, 1.0  # quaternion rows with a . b = 0
    for a, b in [*pairs, boundary]:
        expected = np.concatenate(
            [p.difference(a[s], b[s]) for p, s in zip(task_map.parts, task_map.slices.values())]
        )
        np.testing.assert_array_equal(task_map.difference(a, b), expected)
        np.testing.assert_array_equal(task_map.difference(a[None], b[None])[0], expected)  # batched


# Known solutions


def test_recovers_known_positions(ur5e, rng):
    model, data = ur5e
    task_map = parse_spec("position(tcp)", model)
    for q in random_configurations(model, rng, 10):
        target = target_at(model, task_map, q)
        forward_kinematics(model, data, HOME_Q)
        result = full_solve(model, data, task_map, target)
        assert isinstance(result, IKResult) and result.converged
        assert result.error_norm < 1e-4 and len(result.error_history) == result.iterations + 1
        np.testing.assert_allclose(target_at(model, task_map, result.q), target, atol=1e-4)


def test_recovers_known_poses_from_home(ur5e, pose_map, rng):
    """Targets anywhere in the joint range, any IK branch: the restarts find one."""
    model, data = ur5e
    for q in random_configurations(model, rng, 30):
        target = target_at(model, pose_map, q)
        forward_kinematics(model, data, HOME_Q)
        result = full_solve(model, data, pose_map, target, tol=5e-5)
        assert result.converged, f"target from q = {q}"
        y = target_at(model, pose_map, result.q)
        assert np.linalg.norm(y[:3] - target[:3]) <= 1e-4
        assert quaternion_angle(y[3:], target[3:]) <= 1e-4


def test_data_holds_the_returned_configuration_with_kinematics(ur5e, pose_map, rng):
    model, data = ur5e
    target = target_at(model, pose_map, random_configurations(model, rng, 1)[0])
    result = full_solve(model, data, pose_map, target)
    np.testing.assert_array_equal(data.qpos[:6], result.q)
    np.testing.assert_allclose(pose_map(model, data).y, target_at(model, pose_map, result.q), atol=1e-12)


def test_is_deterministic(ur5e, pose_map, rng):
    model, data = ur5e
    target = target_at(model, pose_map, random_configurations(model, rng, 1)[0])
    first = full_solve(model, data, pose_map, target)
    forward_kinematics(model, data, HOME_Q)
    second = full_solve(model, data, pose_map, target)
    np.testing.assert_array_equal(first.q, second.q)
    assert first.error_history == second.error_history


# Behaviour


def test_error_decreases_monotonically_on_easy_targets(ur5e, pose_map, rng):
    model, data = ur5e
    for _ in range(10):
        target = target_at(model, pose_map, HOME_Q + rng.uniform(-0.1, 0.1, 6))
        forward_kinematics(model, data, HOME_Q)
        result = full_solve(model, data, pose_map, target)
        errors = result.error_history
        assert result.converged and result.iterations <= 5
        assert all(b < a for a, b in pairwise(errors))


@pytest.mark.parametrize("restarts", [0, 3])
def test_unreachable_target_reports_failure_within_limits(ur5e, restarts):
    model, data = ur5e
    task_map = parse_spec("position(tcp)", model)
    result = full_solve(model, data, task_map, np.array([5.0, 0.0, 0.0]), restarts=restarts)
    assert not result.converged
    assert np.all(np.isfinite(result.q)) and within_limits(model, result.q)
    assert np.isfinite(result.error_norm) and 3.9 < result.error_norm < 5.0  # the arm reaches ~1 m
    assert np.all(np.isfinite(result.error_history))


@pytest.mark.parametrize(
    "start",
    [np.zeros(6), np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, 0.0, 0.0])],
    ids=["stretched arm (q = 0)", "wrist singularity (wrist_2 = 0)"],
)
@pytest.mark.parametrize("restarts", [0, 30])
def test_singular_start_does_not_blow_up(ur5e, pose_map, start, restarts):
    model, data = ur5e
    target = target_at(model, pose_map, HOME_Q + 0.2)
    forward_kinematics(model, data, start)
    result = full_solve(model, data, pose_map, target, restarts=restarts)
    assert np.all(np.isfinite(result.q)) and within_limits(model, result.q)
    assert np.all(np.isfinite(result.error_history))
    assert result.converged


def test_singular_target_is_reached(ur5e, pose_map):
    """A pose whose only solutions are singular (arm stretched) still converges, more slowly."""
    model, data = ur5e
    target = target_at(model, pose_map, np.array([0.3, -0.4, 0.0, 0.5, 0.6, 0.7]))
    result = full_solve(model, data, pose_map, target, tol=1e-4)
    assert result.converged


def test_stacked_position_and_alignment_targets_are_met(ur5e, rng):
    """The paper's action: TCP position plus x.x, y.y, z.z of the world and TCP axes."""
    model, data = ur5e
    task_map = parse_spec(ALIGNMENT, model)
    assert task_map.dim == 6
    for q in np.concatenate([HOME_Q + rng.uniform(-0.5, 0.5, (5, 6)), random_configurations(model, rng, 5)]):
        target = target_at(model, task_map, q)
        forward_kinematics(model, data, HOME_Q)
        result = full_solve(model, data, task_map, target)
        assert result.converged, f"target from q = {q}"
        np.testing.assert_allclose(target_at(model, task_map, result.q), target, atol=1e-4)


def test_cup_pointing_down_is_held_across_the_reach_box(ur5e, rng):
    """The taskspace action: a TCP position with the cup pointing down (z_tcp . z_world = -1)."""
    model, data = ur5e
    task_map = parse_spec("position(tcp), scalarProductZZ(world, tcp)", model)
    home_tcp = target_at(model, task_map, HOME_Q)[:3]
    for offset in rng.uniform(-0.15, 0.15, (10, 3)):
        target = np.append(home_tcp + offset, -1.0)
        result = full_solve(model, data, task_map, target)
        assert result.converged


def test_weights_scale_rows_and_zero_drops_them(ur5e, pose_map, rng):
    model, data = ur5e
    target = target_at(model, pose_map, HOME_Q + 0.3)
    target[3:] = [0.0, 1.0, 0.0, 0.0]  # an orientation we do not care about
    weights = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    result = full_solve(model, data, pose_map, target, weights=weights)
    assert result.converged
    np.testing.assert_allclose(target_at(model, pose_map, result.q)[:3], target[:3], atol=1e-4)


def test_posture_pulls_within_the_null_space(ur5e):
    model, data = ur5e
    task_map = parse_spec("position(tcp)", model)
    target = target_at(model, task_map, HOME_Q + 0.1)
    posture = HOME_Q + np.array([0.0, 0.0, 0.0, 0.5, 0.5, 0.5])
    plain = full_solve(model, data, task_map, target, tol=1e-6)
    forward_kinematics(model, data, HOME_Q)
    pulled = full_solve(model, data, task_map, target, tol=1e-6, posture=posture, posture_gain=0.5)
    assert plain.converged and pulled.converged
    assert np.linalg.norm(pulled.q - posture) < np.linalg.norm(plain.q - posture) - 0.1


# Joint limits and other coordinates


def test_joint_limits_hold_on_every_iterate(ur5e, rng):
    """Targets beyond the limits (jointState) and global pose targets: no iterate leaves the range."""
    model, data = ur5e
    recorder = Recording(parse_spec("jointState", model))
    beyond = np.array([8.0, -8.0, 4.0, 7.0, -7.0, 9.0])
    result = full_solve(model, data, recorder, beyond, restarts=0)
    np.testing.assert_allclose(result.q, np.clip(beyond, *JOINT_LIMITS.T))
    pose = Recording(parse_spec(POSE, model))
    for q in random_configurations(model, rng, 5):
        forward_kinematics(model, data, HOME_Q)
        full_solve(model, data, pose, target_at(model, pose.inner, q))
    assert len(recorder.qpos) > 1 and len(pose.qpos) > 20
    assert all(within_limits(model, qpos[:6]) for qpos in recorder.qpos + pose.qpos)


def test_start_outside_the_limits_is_clipped(ur5e, pose_map):
    model, data = ur5e
    target = target_at(model, pose_map, HOME_Q)
    data.qpos[:6] = HOME_Q + np.array([7.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    result = full_solve(model, data, pose_map, target)
    assert result.converged and within_limits(model, result.q)


def test_free_box_in_pick_place_never_moves(pick_place_model, rng):
    model = pick_place_model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_forward(model, data)
    box = model.joint("box")
    box_qpos = slice(box.qposadr[0], box.qposadr[0] + 7)
    data.qpos[box_qpos] = [-0.4, 0.2, 0.3, 0.9, 0.1, 0.3, 0.2]  # an odd, unnormalised pose
    before = data.qpos[box_qpos].copy()
    task_map = Recording(parse_spec(POSE, model))
    for q in random_configurations(model, rng, 5):
        result = full_solve(model, data, task_map, target_at(model, task_map.inner, q))
        assert result.converged and result.q.shape == (6,)
    np.testing.assert_array_equal(data.qpos[box_qpos], before)
    assert all(np.array_equal(qpos[box_qpos], before) for qpos in task_map.qpos)


def test_moves_only_the_named_joints(ur5e):
    model, data = ur5e
    task_map = parse_spec("position(tcp)", model)
    target = target_at(model, task_map, HOME_Q + np.array([0.0, 0.2, -0.3, 0.0, 0.0, 0.0]))
    joints = ("shoulder_lift", "elbow", "wrist_1")
    result = full_solve(model, data, task_map, target, joints=joints)
    assert result.converged and result.q.shape == (3,)
    np.testing.assert_array_equal(data.qpos[[0, 4, 5]], HOME_Q[[0, 4, 5]])


# A precomputed value and the single step


def test_initial_value_skips_the_first_evaluation(ur5e, pose_map):
    model, data = ur5e
    target = target_at(model, pose_map, HOME_Q + 0.05)
    recorder = Recording(pose_map)
    plain = full_solve(model, data, recorder, target)
    evaluations = len(recorder.qpos)
    forward_kinematics(model, data, HOME_Q)
    value = pose_map(model, data)
    reused = full_solve(model, data, recorder, target, initial_value=value)
    assert len(recorder.qpos) - evaluations == evaluations - 1
    np.testing.assert_array_equal(plain.q, reused.q)
    assert plain.error_history == reused.error_history


def test_initial_value_at_the_target_leaves_data_alone(ur5e, pose_map):
    model, data = ur5e
    value = pose_map(model, data)
    qpos, xpos = data.qpos.copy(), data.xpos.copy()
    result = full_solve(model, data, pose_map, value.y, initial_value=value)
    assert result.converged and result.iterations == 0
    np.testing.assert_array_equal(data.qpos, qpos)
    np.testing.assert_array_equal(data.xpos, xpos)


def test_step_is_one_paper_step_and_writes_nothing(ur5e, pose_map):
    model, data = ur5e
    solver = DlsSolver(model, pose_map, options=IKOptions(damping=1e-3, adaptive_damping=0.0))
    target = target_at(model, pose_map, HOME_Q + 0.05)
    qpos, value = data.qpos.copy(), pose_map(model, data)
    y, J, q = value.y.copy(), value.J.copy(), data.qpos[:6].copy()
    q_next, _ = solver.step(q, value, target)
    np.testing.assert_array_equal(data.qpos, qpos)
    np.testing.assert_array_equal(q, qpos[:6])
    np.testing.assert_array_equal(value.y, y)
    np.testing.assert_array_equal(value.J, J)
    expected = HOME_Q + dls_step(J, pose_map.difference(target, y), 1e-3)
    np.testing.assert_allclose(q_next, expected, atol=1e-12)
    # The step brings the pose closer, and is bounded and clipped.
    before = np.linalg.norm(pose_map.difference(target, y))
    after = np.linalg.norm(pose_map.difference(target, target_at(model, pose_map, q_next)))
    assert after < 0.1 * before
    bounded = DlsSolver(model, pose_map, options=IKOptions(max_step=0.1))
    far, _ = bounded.step(q, value, target_at(model, pose_map, -HOME_Q))
    assert np.linalg.norm(far - HOME_Q) <= 0.1 + 1e-12


def test_step_reports_the_linearised_residual_and_matches_one_solve_iteration(ur5e, pose_map):
    model, data = ur5e
    options = IKOptions(damping=1e-3, max_step=0.2, max_iters=1, restarts=0, tol=1e-12)
    solver = DlsSolver(model, pose_map, options=options)
    value, q = pose_map(model, data), data.qpos[:6].copy()
    for delta in (0.05, -0.3, 1.0):  # small, clipped by max_step, and far
        target = target_at(model, pose_map, HOME_Q + delta)
        q_next, residual = solver.step(q, value, target)
        predicted = pose_map.difference(target, value.y) - value.J @ (q_next - HOME_Q)
        assert residual == pytest.approx(np.linalg.norm(predicted), rel=1e-12, abs=1e-15)
        scratch = mujoco.MjData(model)
        scratch.qpos[:] = data.qpos
        result = solver.solve(scratch, target, value)  # one iteration from the same value
        np.testing.assert_array_equal(result.q, q_next)


def test_step_gives_the_clipped_start_for_a_non_finite_step(ur5e, pose_map):
    model, data = ur5e
    solver = DlsSolver(model, pose_map)
    value = pose_map(model, data)
    q = data.qpos[:6].copy()
    q[0] = 9.0  # outside the limits
    q_next, _ = solver.step(q, value, np.full(7, np.nan))
    np.testing.assert_array_equal(q_next, np.clip(q, *JOINT_LIMITS.T))


# Bad input


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"tol": 0.0}, "tol must be > 0; got 0.0"),
        ({"tol": float("nan")}, "tol must be > 0; got nan"),
        ({"max_iters": 0}, "max_iters must be an integer >= 1; got 0"),
        ({"max_iters": 2.5}, "max_iters must be an integer >= 1; got 2.5"),
        ({"restarts": -1}, "restarts must be an integer >= 0; got -1"),
        ({"seed": True}, "seed must be an integer >= 0; got True"),
        ({"damping": -1e-3}, "damping must be > 0; got -0.001"),
        ({"adaptive_damping": -1.0}, "adaptive_damping must be >= 0; got -1.0"),
        ({"max_step": 0}, "max_step must be > 0; got 0"),
        ({"max_step": "big"}, "max_step must be a number; got 'big'"),
        ({"weights": -np.ones(7)}, "weights must be >= 0"),
        ({"weights": np.ones((2, 2))}, r"weights has shape \(2, 2\); expected a 1-D sequence"),
        ({"posture": [0.0, np.inf]}, "posture must be finite"),
        ({"posture_gain": -0.1}, "posture_gain must be >= 0; got -0.1"),
        ({"posture_gain": [0.1, -0.1]}, "posture_gain must be >= 0"),
    ],
)
def test_bad_options_raise_a_clear_error_when_built(options, match):
    with pytest.raises(InvalidConfig, match=match):
        IKOptions(**options)


def test_options_are_frozen_and_normalised():
    options = IKOptions(weights=np.ones(3), posture_gain=np.array([0.1, 0.2]), max_step=1)
    assert options.weights == (1.0, 1.0, 1.0) and options.posture_gain == (0.1, 0.2)
    assert isinstance(options.max_step, float)
    with pytest.raises(AttributeError):
        options.tol = 1.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"options": IKOptions(weights=np.ones(3))}, r"weights has shape \(3,\); expected \(7,\)"),
        ({"options": IKOptions(posture=np.zeros(7))}, r"posture has shape \(7,\); expected \(6,\)"),
        ({"options": IKOptions(posture_gain=np.ones(2))}, r"posture_gain has shape \(2,\); expected \(6,\)"),
        ({"joints": ("elbow", "elbow")}, "joints must be distinct joint names"),
        ({"joints": "elbow"}, "joints must be a sequence of joint names"),
    ],
)
def test_bad_solver_setup_raises_a_clear_error(ur5e, pose_map, kwargs, match):
    model, _ = ur5e
    with pytest.raises(InvalidConfig, match=match):
        DlsSolver(model, pose_map, **kwargs)


def test_unknown_joint_lists_the_models_joints(ur5e, pose_map):
    model, _ = ur5e
    with pytest.raises(UnknownName, match="unknown joint 'box'; the model's joints: elbow, shoulder_lift"):
        DlsSolver(model, pose_map, ("box",))


@pytest.mark.parametrize(
    ("target", "match"),
    [
        (np.zeros(3), r"target has shape \(3,\); expected \(7,\)"),
        (np.full(7, np.nan), "target must be finite"),
    ],
)
def test_bad_target_raises_a_clear_error(ur5e, pose_map, target, match):
    model, data = ur5e
    with pytest.raises(InvalidConfig, match=match):
        DlsSolver(model, pose_map).solve(data, target)


def test_unknown_option_is_named():
    with pytest.raises(TypeError, match="tolerance"):
        IKOptions(tolerance=1e-3)  # type: ignore[call-arg]


def test_a_free_joint_cannot_be_moved(pick_place_model):
    task_map = parse_spec("position(tcp)", pick_place_model)
    with pytest.raises(InvalidConfig, match="joint 'box' is a free joint, not a hinge or slide joint"):
        DlsSolver(pick_place_model, task_map, ("box",))


def test_bad_initial_value_and_state_are_rejected(ur5e, pose_map):
    model, data = ur5e
    target = target_at(model, pose_map, HOME_Q)
    value = parse_spec("position(tcp)", model)(model, data)
    solver = DlsSolver(model, pose_map)
    with pytest.raises(InvalidConfig, match=r"initial_value has y \(3,\)"):
        solver.solve(data, target + 0.1, value)
    data.qpos[2] = np.nan
    with pytest.raises(InvalidConfig, match="non-finite joint positions"):
        solver.solve(data, target)


def test_solver_pickles_and_solves_the_same(ur5e, pose_map, rng):
    import pickle

    model, data = ur5e
    solver = DlsSolver(model, pose_map, options=IKOptions(posture=tuple(HOME_Q)))
    target = target_at(model, pose_map, random_configurations(model, rng, 1)[0])
    copy = pickle.loads(pickle.dumps(solver))
    scratch = mujoco.MjData(copy.model)
    scratch.qpos[:] = data.qpos
    first = solver.solve(data, target)
    second = copy.solve(scratch, target)
    np.testing.assert_array_equal(first.q, second.q)
