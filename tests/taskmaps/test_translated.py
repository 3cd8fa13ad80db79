"""translated(): a map's value with the mocap `target` moved, against moving it and evaluating again."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from tsrl.exceptions import NotRelabelable, TsrlError
from tsrl.kinematics import forward_kinematics, random_configurations
from tsrl.taskmaps import TASK_MAPS, known_maps, parse_spec

from .conftest import EXAMPLE_ARGS


def _specs_reading_target() -> list[str]:
    """Every registered map with `target` as each of its frame arguments, and its velocity."""
    specs = []
    for name in known_maps():
        kinds = TASK_MAPS[name].args
        if "frame" not in kinds:
            continue
        for i in range(len(kinds)):
            args = list(EXAMPLE_ARGS["frame"][: len(kinds)])
            args[i] = "target"
            specs += [f"{name}({', '.join(args)})", f"velocity({name}({', '.join(args)}))"]
    return specs


def _moved(task_map, model, data, delta: np.ndarray) -> np.ndarray:
    """The map's value with the target's mocap body moved by delta; data is restored afterwards."""
    mocap_pos = data.mocap_pos.copy()
    data.mocap_pos[0] += delta
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    y = task_map(model, data).y
    data.mocap_pos[:] = mocap_pos
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    return y


@pytest.fixture
def moving_arm(ur5e, rng):
    """The reach scene at a random configuration with random joint velocities."""
    model, data = ur5e
    forward_kinematics(model, data, random_configurations(model, rng, 1)[0])
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    return model, data


@pytest.mark.parametrize(
    "spec", ["position(target)", "positionDiff(tcp, target)", "positionDiff(target, tcp)", "fs2", "simple"]
)
def test_translated_equals_moving_the_target(spec, moving_arm, rng):
    model, data = moving_arm
    task_map = parse_spec(spec, model)
    y = task_map(model, data).y
    for delta in rng.uniform(-0.2, 0.2, size=(3, 3)):
        np.testing.assert_allclose(
            task_map.translated(y, "target", delta), _moved(task_map, model, data, delta)
        )


@pytest.mark.parametrize("spec", _specs_reading_target())
def test_every_map_translates_exactly_or_refuses(spec, moving_arm, rng):
    model, data = moving_arm
    task_map = parse_spec(spec, model)
    y = task_map(model, data).y
    delta = rng.uniform(-0.2, 0.2, 3)
    try:
        translated = task_map.translated(y, "target", delta)
    except NotRelabelable as err:  # only positionRel needs R_g or p_f, which y does not hold
        assert "positionRel" in spec and spec in str(err) and "'target'" in str(err)
        return
    np.testing.assert_allclose(translated, _moved(task_map, model, data, delta), atol=1e-12)


@pytest.mark.parametrize(
    "spec", ["positionRel(tcp, target)", "positionRel(target, tcp)", "velocity(positionRel(target, tcp))"]
)
def test_maps_that_need_more_than_y_refuse(spec, reach_model):
    task_map = parse_spec(spec, reach_model)
    with pytest.raises(TsrlError, match=r"cannot be recomputed"):
        task_map.translated(np.zeros(task_map.dim), "target", np.ones(3))


def test_distance_refuses_a_translation_of_its_geoms_body(reach_model):
    distance = parse_spec("distance(suction_cup, table)", reach_model)
    assert distance.frames == ("suction_cup", "table", "world")
    with pytest.raises(NotRelabelable, match=r"distance\(suction_cup, table\)"):
        distance.translated(np.zeros(1), "world", np.ones(3))


def test_maps_not_reading_the_frame_are_unchanged(moving_arm, rng):
    model, data = moving_arm
    stack = parse_spec("position(tcp), quaternion(tcp), jointLimits, accumulatedCollisions", model)
    y = stack(model, data).y
    out = stack.translated(y, "target", rng.uniform(-0.2, 0.2, 3))
    np.testing.assert_array_equal(out, y)
    assert out is not y


def test_batched_translation_equals_per_row(moving_arm, rng):
    model, data = moving_arm
    stack = parse_spec("fs2", model)
    ys = np.stack([stack(model, data).y + rng.normal(size=stack.dim) for _ in range(5)])
    deltas = rng.uniform(-0.2, 0.2, size=(5, 3))
    batched = stack.translated(ys, "target", deltas)
    assert batched.shape == ys.shape
    for y, delta, row in zip(ys, deltas, batched):
        np.testing.assert_array_equal(stack.translated(y, "target", delta), row)
    one_delta = stack.translated(ys, "target", deltas[0])  # one delta for the whole batch
    np.testing.assert_array_equal(one_delta, np.stack([stack.translated(y, "target", deltas[0]) for y in ys]))
