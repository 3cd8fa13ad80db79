"""Relabelling rules (taskmaps/relabel.py): a map's value with the mocap `target` moved (and turned),
computed from its old value, against moving the target in MuJoCo and evaluating the map again."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.envs import parse_observation
from tsrl.exceptions import NotRelabelable
from tsrl.kinematics import forward_kinematics, random_configurations
from tsrl.taskmaps import TASK_MAPS, known_maps, parse_spec
from tsrl.taskmaps.relabel import FrameMove, FramePose, check_relabelable, relabelled

from .conftest import EXAMPLE_ARGS

FRAMES = EXAMPLE_ARGS["frame"]  # the other frames a map reads: ("tcp", "upper_arm_link")


def _specs_reading_target() -> list[str]:
    """Every registered map with `target` as each of its frame arguments, and its velocity."""
    specs = []
    for name in known_maps():
        kinds = TASK_MAPS[name].args
        if "frame" not in kinds:
            continue
        for i in range(len(kinds)):
            args = list(FRAMES[: len(kinds)])
            args[i] = "target"
            specs += [f"{name}({', '.join(args)})", f"velocity({name}({', '.join(args)}))"]
    return specs


def _kinematics(model, data):
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)


def _moved(task_map, model, data, delta, quat=None) -> np.ndarray:
    """The map's value with the target's mocap body moved by delta (and turned to quat); data restored."""
    pos, old = data.mocap_pos.copy(), data.mocap_quat.copy()
    data.mocap_pos[0] += delta
    if quat is not None:
        data.mocap_quat[0] = quat
    _kinematics(model, data)
    y = task_map(model, data).y
    data.mocap_pos[:], data.mocap_quat[:] = pos, old
    _kinematics(model, data)
    return y


def _move(model, data, delta, quat=None, known=FRAMES) -> FrameMove:
    """The FrameMove of the target by delta (and to quat), with the poses of `known` frames given."""
    poses = {
        f: FramePose(
            parse_spec(f"position({f})", model)(model, data).y,
            parse_spec(f"quaternion({f})", model)(model, data).y,
        )
        for f in known
    }
    old = data.xquat[model.site_bodyid[model.site("target").id]].copy()
    return FrameMove("target", delta, old, old if quat is None else quat, quat is not None, poses)


@pytest.fixture
def moving_arm(ur5e, rng):
    """The reach scene at a random configuration with random joint velocities."""
    model, data = ur5e
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    return model, data


def _random_quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@pytest.mark.parametrize("spec", _specs_reading_target())
def test_translation_relabels_every_map_exactly_or_refuses(spec, moving_arm, rng):
    model, data = moving_arm
    task_map = parse_spec(spec, model)
    y = task_map(model, data).y
    delta = rng.uniform(-0.2, 0.2, 3)
    try:
        new = relabelled(task_map, y, _move(model, data, delta, known=()))
    except NotRelabelable as err:  # positionRel(target, g) needs R_g; its velocity, p_f
        assert "positionRel(target" in spec and spec in str(err) and "'target'" in str(err)
        return
    np.testing.assert_allclose(new, _moved(task_map, model, data, delta), atol=1e-12)


@pytest.mark.parametrize("spec", _specs_reading_target())
def test_translation_and_rotation_relabel_every_map_exactly_or_refuse(spec, moving_arm, rng):
    model, data = moving_arm
    task_map = parse_spec(spec, model)
    y = task_map(model, data).y
    delta, quat = rng.uniform(-0.2, 0.2, 3), _random_quat(rng)
    try:
        new = relabelled(task_map, y, _move(model, data, delta, quat))
    except NotRelabelable as err:  # velocities whose Jacobian reads the target's orientation
        assert spec.startswith("velocity(") and spec in str(err)
        assert "scalarProduct" in spec or "positionRel" in spec
        return
    expected = _moved(task_map, model, data, delta, quat)
    if spec.startswith("quaternion(") and new @ expected < 0:
        expected = -expected  # the same orientation
    np.testing.assert_allclose(new, expected, atol=1e-12)


@pytest.mark.parametrize(
    ("spec", "reason"),
    [
        ("positionRel(target, tcp)", "orientation of frame 'tcp'"),
        ("velocity(positionRel(target, tcp))", "Jacobian of positionRel"),
        ("quaternionDiff(tcp, target)", "orientation of frame 'tcp'"),
    ],
)
def test_maps_that_need_what_the_goal_does_not_carry_are_refused(spec, reason, reach_model):
    task_map = parse_spec(spec, reach_model)
    z3, q = np.zeros(3), np.array([1.0, 0, 0, 0])
    move = FrameMove("target", z3, q, q, spec.startswith("quaternionDiff"), {})
    with pytest.raises(NotRelabelable, match=reason):
        check_relabelable(task_map, move)


def test_distance_refuses_a_move_of_its_geoms_body(reach_model):
    distance = parse_spec("distance(suction_cup, table)", reach_model)
    q = np.array([1.0, 0, 0, 0])
    with pytest.raises(NotRelabelable, match=r"distance\(suction_cup, table\)"):
        relabelled(distance, np.zeros(1), FrameMove("world", np.ones(3), q, q, False, {}))


def test_maps_not_reading_the_frame_are_unchanged(moving_arm, rng):
    model, data = moving_arm
    stack = parse_spec("position(tcp), quaternion(tcp), jointLimits, accumulatedCollisions", model)
    y = stack(model, data).y
    out = relabelled(stack, y, _move(model, data, rng.uniform(-0.2, 0.2, 3), _random_quat(rng)))
    np.testing.assert_array_equal(out, y)
    assert out is not y


def test_batched_relabel_equals_per_row(moving_arm, rng):
    model, data = moving_arm
    stack = parse_observation("fs2, scalarProductXZ(tcp, target), vectorY(target)", model)
    ys = np.stack([stack(model, data).y + rng.normal(size=stack.dim) for _ in range(5)])
    deltas = rng.uniform(-0.2, 0.2, size=(5, 3))
    quats = np.stack([_random_quat(rng) for _ in range(5)])
    one = _move(model, data, deltas[0], quats[0])
    tcp = one.known["tcp"]
    batch_known = {"tcp": FramePose(np.tile(tcp.pos, (5, 1)), np.tile(tcp.quat, (5, 1)))}
    batched = relabelled(
        stack, ys, FrameMove("target", deltas, np.tile(one.old_quat, (5, 1)), quats, True, batch_known)
    )
    assert batched.shape == ys.shape
    for i, y in enumerate(ys):
        row = relabelled(stack, y, FrameMove("target", deltas[i], one.old_quat, quats[i], True, one.known))
        np.testing.assert_allclose(batched[i], row, atol=1e-15)
