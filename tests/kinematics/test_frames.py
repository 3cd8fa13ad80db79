"""Index helpers and the controlled joints of tsrl.kinematics."""

import mujoco
import numpy as np
import pytest

from tsrl.exceptions import InvalidConfig, UnknownName
from tsrl.kinematics import (
    arm_qpos_indices,
    as_slice,
    controlled_joints,
    joint_ids,
    joint_limits,
    random_configurations,
)


def test_as_slice_views_consecutive_indices_and_keeps_the_others():
    data = np.arange(10.0)
    assert as_slice([3, 4, 5]) == slice(3, 6)
    assert as_slice(np.array([0])) == slice(0, 1)
    scattered = as_slice([2, 7, 3])
    np.testing.assert_array_equal(scattered, [2, 7, 3])
    np.testing.assert_array_equal(data[as_slice([3, 4, 5])], data[[3, 4, 5]])
    assert isinstance(as_slice([5, 4, 3]), np.ndarray)  # descending is not a slice


# The controlled joints of any model

UNLIMITED = """
<mujoco>
  <worldbody>
    <body><joint name="spin" axis="0 0 1"/><geom size="0.1"/>
      <body pos="0.2 0 0"><joint name="rail" type="slide" axis="1 0 0"/><geom size="0.05"/>
        <body pos="0.2 0 0"><joint name="ball" type="ball"/><geom size="0.05"/></body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def test_default_joints_are_every_hinge_and_slide_joint():
    from tsrl.assets import load_model
    from tsrl.assets.ur5e import JOINT_LIMITS, JOINT_NAMES

    model = load_model("pick_place")  # the box's free joint is not controlled
    assert controlled_joints(model) == JOINT_NAMES
    np.testing.assert_array_equal(joint_limits(model), JOINT_LIMITS)
    np.testing.assert_array_equal(arm_qpos_indices(model), np.arange(6))
    assert controlled_joints(model, ["elbow", "wrist_1"]) == ("elbow", "wrist_1")
    other = mujoco.MjModel.from_xml_string(UNLIMITED)
    assert controlled_joints(other) == ("spin", "rail")
    np.testing.assert_array_equal(joint_limits(other), [[-np.inf, np.inf]] * 2)


def test_bad_joints_are_named():
    model = mujoco.MjModel.from_xml_string(UNLIMITED)
    with pytest.raises(UnknownName, match="unknown joint 'elbow'; the model's joints: ball, rail, spin"):
        joint_ids(model, ["elbow"])
    with pytest.raises(
        InvalidConfig, match="joint 'ball' is a ball joint, not a hinge or slide joint.*: spin, rail"
    ):
        joint_ids(model, ["ball"])
    with pytest.raises(InvalidConfig, match="joints must be distinct"):
        joint_ids(model, ["spin", "spin"])
    with pytest.raises(InvalidConfig, match="joints must be distinct"):
        joint_ids(model, [])
    with pytest.raises(InvalidConfig, match="no hinge or slide joints"):
        joint_ids(
            mujoco.MjModel.from_xml_string(
                "<mujoco><worldbody><body><freejoint/><geom size='1'/></body></worldbody></mujoco>"
            )
        )


def test_random_configurations_of_unlimited_joints():
    model = mujoco.MjModel.from_xml_string(UNLIMITED)
    q = random_configurations(model, np.random.default_rng(0), 100, ["spin"])
    assert q.shape == (100, 1) and (np.abs(q) <= np.pi).all()
    with pytest.raises(InvalidConfig, match="slide joint 'rail' has no limits"):
        random_configurations(model, np.random.default_rng(0), 1)
