"""The spec parser: presets, slices, canonical text, and every error path with its message."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from tsrl.assets.ur5e import HOME_Q
from tsrl.envs import OBS_PRESETS
from tsrl.envs import parse_observation as parse_spec  # the parser with the environments' presets
from tsrl.exceptions import SpecError, UnknownName, UnknownTaskMap
from tsrl.kinematics import forward_kinematics
from tsrl.taskmaps import Position, Stack, known_maps

#: The feature order of DESIGN.md's observation table.
PRESET_FEATURES = {
    "baseline": ["position(tcp)", "velocity(position(tcp))"],
    "simple": ["positionDiff(tcp, target)", "velocity(positionDiff(tcp, target))"],
    "fs0": ["position(tcp)", "position(target)", "positionDiff(tcp, target)"],
}
PRESET_FEATURES["fs1"] = [
    *PRESET_FEATURES["fs0"],
    "velocity(position(tcp))",
    "velocity(positionDiff(tcp, target))",
]
PRESET_FEATURES["fs2"] = [*PRESET_FEATURES["fs1"], "quaternion(tcp)", "quaternionDiff(tcp, target)"]
#: The paper's pick-and-place features phi_1..phi_6, and with the box relative to the TCP.
PRESET_FEATURES["pick_phi"] = [
    "position(box)",
    "position(target)",
    "position(tcp)",
    "quaternion(tcp)",
    "positionDiff(box, target)",
    "positionDiff(tcp, target)",
]
PRESET_FEATURES["pick_phi_plus"] = [
    *PRESET_FEATURES["pick_phi"],
    "positionDiff(box, tcp)",
    "velocity(position(box))",
    "suction(suction)",
]


@pytest.mark.parametrize(
    ("name", "dim"), [("baseline", 6), ("simple", 6), ("fs0", 9), ("fs1", 15), ("fs2", 23)]
)
def test_preset_dimension_and_slices_tile_the_vector(name, dim, ur5e):
    model, data = ur5e
    stack = parse_spec(name, model)
    y, J = stack(model, data)
    assert stack.dim == dim and y.shape == (dim,) and J.shape == (dim, model.nv)
    spans = list(stack.slices.values())
    assert spans[0].start == 0 and spans[-1].stop == dim
    assert all(a.stop == b.start for a, b in pairwise(spans))


def test_presets_list_the_design_features_in_order(reach_model):
    from tsrl.assets import load_model

    pick_model = load_model("pick_place")
    assert set(OBS_PRESETS) == set(PRESET_FEATURES)
    for name, features in PRESET_FEATURES.items():
        model = pick_model if name.startswith("pick") else reach_model
        assert list(parse_spec(name, model).slices) == features


def test_slices_name_each_parts_rows(ur5e):
    model, data = ur5e
    stack = parse_spec("fs2", model)
    y = stack(model, data).y
    for spec, rows in stack.slices.items():
        np.testing.assert_array_equal(y[rows], parse_spec(spec, model)(model, data).y)


def test_nested_presets_expand_in_place(reach_model):
    stack = parse_spec("fs1, quaternion(tcp), scalarProductZZ(world, tcp)", reach_model)
    assert stack.dim == 15 + 4 + 1
    assert list(stack.slices) == [*PRESET_FEATURES["fs1"], "quaternion(tcp)", "scalarProductZZ(world, tcp)"]


def test_a_single_map_is_a_stack_of_one(ur5e):
    model, data = ur5e
    stack = parse_spec("position(tcp)", model)
    assert isinstance(stack, Stack) and len(stack) == 1
    assert stack.slices == {"position(tcp)": slice(0, 3)}
    np.testing.assert_array_equal(stack(model, data).y, Position(model, "tcp")(model, data).y)


def test_in_place_returns_the_maps_own_buffers_with_the_calls_numbers(ur5e, rng):
    model, data = ur5e
    stack = parse_spec("fs2", model)
    first = stack.in_place(model, data)
    for q in HOME_Q + rng.uniform(-0.5, 0.5, (3, 6)):
        forward_kinematics(model, data, q)
        value = stack.in_place(model, data)
        assert value.y is first.y and value.J is first.J  # the same arrays, overwritten
        fresh = stack(model, data)
        assert fresh.y is not value.y and fresh.J is not value.J
        np.testing.assert_array_equal(value.y, fresh.y)
        np.testing.assert_array_equal(value.J, fresh.J)


def test_velocity_of_a_map_in_the_same_stack_equals_the_velocity_map_alone(ur5e, rng):
    model, data = ur5e
    for spec in ("velocity(positionDiff(tcp, upper_arm_link)), positionDiff(tcp, upper_arm_link)", "fs2"):
        stack = parse_spec(spec, model)
        forward_kinematics(model, data, HOME_Q + rng.uniform(-0.5, 0.5, 6))
        data.qvel[:6] = rng.normal(size=6)
        value = stack(model, data)
        for part, rows in zip(stack.parts, stack.slices.values()):
            alone = parse_spec(part.spec, model)(model, data)
            np.testing.assert_array_equal(value.y[rows], alone.y)
            np.testing.assert_array_equal(value.J[rows], alone.J)


def test_repeated_parts_get_numbered_keys(reach_model):
    stack = parse_spec("fs0, position(tcp), position(tcp)", reach_model)
    assert list(stack.slices)[-2:] == ["position(tcp)#2", "position(tcp)#3"]
    assert stack.slices["position(tcp)#3"] == slice(12, 15)


def test_repeated_parts_carry_the_value_and_jacobian_of_their_first_occurrence(ur5e):
    model, data = ur5e
    forward_kinematics(model, data, [0.3, -1.2, 1.4, -1.9, -1.3, 0.4])
    data.qvel[:6] = [0.1, -0.2, 0.3, 0.2, -0.1, 0.5]
    spec = "velocity(positionDiff(tcp, target)), quaternion(tcp)"
    stack = parse_spec(f"{spec}, position(tcp), {spec}", model)
    once = parse_spec(spec, model)(model, data)
    y, J = stack(model, data)
    for rows in (slice(0, 7), slice(10, 17)):
        np.testing.assert_array_equal(y[rows], once.y)
        np.testing.assert_array_equal(J[rows], once.J)


def test_canonical_spec_round_trips_and_ignores_whitespace(reach_model):
    stack = parse_spec(
        " position( tcp ),velocity(positionDiff(tcp,target)) ,\taccumulatedCollisions()", reach_model
    )
    assert stack.spec == "position(tcp), velocity(positionDiff(tcp, target)), accumulatedCollisions"
    assert parse_spec(stack.spec, reach_model).spec == stack.spec


def test_known_maps_has_every_rai_symbol_and_suction():
    expected = {
        "suction",  # not a RAI symbol: the suction cup's state (tsrl's own)
        "position",
        "positionDiff",
        "positionRel",
        "quaternion",
        "quaternionDiff",
        "vectorX",
        "vectorY",
        "vectorZ",
        *(f"scalarProduct{a}{b}" for a in "XYZ" for b in "XYZ"),
        "distance",
        "accumulatedCollisions",
        "oppose",
        "gripperWidth",  # not a RAI symbol: a gripper's opening width (tsrl's own)
        "jointState",
        "jointLimits",
        "velocity",
    }
    assert set(known_maps()) == expected


def test_unknown_map_lists_known_maps_and_presets(reach_model):
    with pytest.raises(UnknownTaskMap, match="'positon'") as err:
        parse_spec("fs0, positon(tcp)", reach_model)
    assert (
        "positionDiff" in str(err.value) and "fs2" in str(err.value) and "scalarProductZZ" in str(err.value)
    )


def test_unknown_map_inside_velocity(reach_model):
    with pytest.raises(UnknownTaskMap, match="'tcp'"):
        parse_spec("velocity(tcp)", reach_model)


def test_unknown_frame_lists_sites_and_bodies(reach_model):
    with pytest.raises(UnknownName, match="unknown frame 'tpc'") as err:
        parse_spec("positionDiff(tpc, target)", reach_model)
    assert "tcp" in str(err.value) and "upper_arm_link" in str(err.value) and "world" in str(err.value)


def test_unknown_geom_lists_geoms(reach_model):
    with pytest.raises(UnknownName, match="unknown geom 'cup'") as err:
        parse_spec("distance(cup, table)", reach_model)
    assert "suction_cup" in str(err.value)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("positionDiff(tcp)", r"positionDiff expects 2 argument\(s\) \(frame, frame\), got 1 at position 0"),
        ("position", r"position expects 1 argument\(s\) \(frame\), got 0"),
        ("jointState(tcp)", r"jointState expects 0 argument\(s\) \(none\), got 1"),
        (
            "fs0, velocity(position(tcp), position(target))",
            r"velocity expects 1 argument\(s\) \(map\), got 2 at position 5",
        ),
    ],
)
def test_wrong_argument_count_says_the_expected_count(spec, message, reach_model):
    with pytest.raises(SpecError, match=message):
        parse_spec(spec, reach_model)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("position(tcp", r"expected '\)', found the end at position 12"),
        ("position(tcp)), fs0", r"expected the end, found '\)' at position 13"),
        ("fs0,, fs1", r"expected a name, found ',' at position 4"),
        ("position((tcp)", r"expected a name, found '\(' at position 9"),
        ("", r"empty spec"),
        (
            "position(position(tcp))",
            r"argument 1 of position must be a frame name, got position\(tcp\) at position 9",
        ),
        ("fs1(tcp)", r"preset fs1 takes no arguments at position 0"),
        ("velocity(fs1)", r"argument 1 of velocity must be one task map, not a preset at position 9"),
        ("velocity(velocity(position(tcp)))", r"velocity of a velocity is not supported"),
    ],
)
def test_syntax_errors_give_the_position(spec, message, reach_model):
    with pytest.raises(SpecError, match=message):
        parse_spec(spec, reach_model)


def test_spec_errors_quote_the_spec(reach_model):
    with pytest.raises(SpecError, match=r"of spec 'position\(tcp'"):
        parse_spec("position(tcp", reach_model)
