"""The Controller computes the environment's own features and IK step from a measured state (no
physics), holds on bad input, keeps the TCP target in the workspace, and imports without torch."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from tsrl.deploy.controller import (
    GOAL_OUTSIDE_WORKSPACE,
    MISSING_OBJECT,
    NONFINITE_ACTION,
    NONFINITE_GOAL,
    NONFINITE_STATE,
    STALE_STATE,
    Controller,
    ControllerOptions,
)
from tsrl.deploy.exported import exported_env
from tsrl.exceptions import InvalidConfig


def measured(env, controller):
    """The env's true state as a robot would report it: q, qd (the arm's), objects (pose + qvel), the
    gripper's width (None without one)."""
    data = env.data
    q = data.qpos[controller._qpos].copy()
    qd = data.qvel[controller._dofs].copy()
    objects = {
        body: np.concatenate([data.qpos[a : a + 7], data.qvel[d : d + 6]])
        for body, (a, d) in controller._objects.items()
    }
    return q, qd, objects, env.interface.measure_tool(data)


@pytest.mark.parametrize(
    "name", ["ur5e_reach", "panda_pick_place", "ur5e_reach_history", "panda_pick_place_gripper"]
)
def test_features_and_joint_targets_are_the_environments_own(name, request):
    folder = request.getfixturevalue(name)
    controller = Controller.from_export(folder)
    env = exported_env(folder, controller.contract)
    tool = env.interface.tool_ctrl
    T = controller.control_period
    for episode in range(2):
        obs, _ = env.reset(seed=episode)
        q, qd, objects, width = measured(env, controller)
        controller.reset(q, 0.0, obs["desired_goal"])
        for k in range(env.task.episode_steps):
            controller.act(q, qd, objects, t=k * T, stamp=k * T, tool=width)
            cycle = controller.last
            assert set(cycle.faults) <= {"workspace_clip", "joint_limit"}  # reported; it acted (q_ik)
            # Equal to the bit, but with a gripper: the robot reports one width, the simulated fingers
            # may differ by a few nm (the controller places them symmetrically), which moves the hand's
            # centre of mass and so the Jacobian's rounding (1e-12).
            atol = 1e-12 if width is None else 1e-9
            np.testing.assert_allclose(cycle.observation, obs["observation"], rtol=0, atol=atol)
            if width is None:
                np.testing.assert_array_equal(cycle.observation, obs["observation"])
            np.testing.assert_array_equal(cycle.achieved_goal, obs["achieved_goal"])
            np.testing.assert_array_equal(cycle.desired_goal, obs["desired_goal"])
            # The env stepped with the controller's action commands the controller's IK targets and tool.
            obs, *_ = env.step(cycle.applied_action)
            np.testing.assert_allclose(env.data.ctrl[env.bound_robot.ctrl], cycle.q_ik, rtol=0, atol=atol)
            if tool is not None:
                assert env.data.ctrl[tool] == cycle.tool
            q, qd, objects, width = measured(env, controller)


def reset_at_home(controller):
    env = exported_env(controller.folder, controller.contract)
    obs, _ = env.reset(seed=0)
    q = env.data.qpos[controller._qpos].copy()
    controller.reset(q, 0.0, obs["desired_goal"])
    return q, obs["desired_goal"]


def test_a_nan_reading_a_stale_state_and_a_nan_goal_hold_the_arm(ur5e_reach):
    controller = Controller.from_export(ur5e_reach)
    q, goal = reset_at_home(controller)
    zero = np.zeros_like(q)
    T = controller.control_period
    controller.act(q, zero, t=0.0, stamp=0.0)
    assert controller.last.faults in ((), ("workspace_clip",))
    bad = q.copy()
    bad[2] = np.nan
    cases = [
        ({"joint_positions": bad, "joint_velocities": zero, "t": T, "stamp": T}, NONFINITE_STATE),
        (
            {"joint_positions": q, "joint_velocities": zero + np.inf, "t": 2 * T, "stamp": 2 * T},
            NONFINITE_STATE,
        ),
        (
            {"joint_positions": q, "joint_velocities": zero, "t": 3 * T, "stamp": 3 * T - 0.03},
            STALE_STATE,
        ),  # 30 ms old
        (
            {"joint_positions": q, "joint_velocities": zero, "t": 4 * T, "stamp": 0.0},
            STALE_STATE,
        ),  # not newer
        (
            {
                "joint_positions": q,
                "joint_velocities": zero,
                "goal": goal * np.nan,
                "t": 5 * T,
                "stamp": 5 * T,
            },
            NONFINITE_GOAL,
        ),
    ]
    for kwargs, fault in cases:
        target = controller.act(**kwargs)
        cycle = controller.last
        assert fault in cycle.faults and cycle.held
        assert np.isfinite(target).all() and cycle.action is None  # the policy did not run
    controller.set_goal(goal)
    controller.act(q, zero, t=6 * T, stamp=6 * T)
    assert not controller.last.held  # a good state acts again


def test_a_missing_object_holds(panda_pick_place):
    controller = Controller.from_export(panda_pick_place)
    q, _ = reset_at_home(controller)
    controller.act(q, np.zeros_like(q), {}, t=0.0, stamp=0.0)
    assert MISSING_OBJECT in controller.last.faults


def test_a_nonfinite_action_holds(ur5e_reach):
    controller = Controller.from_export(ur5e_reach)
    q, _ = reset_at_home(controller)
    controller.policy = lambda inputs: np.full(3, np.nan)  # a policy gone bad
    target = controller.act(q, np.zeros_like(q), t=0.0, stamp=0.0)
    assert controller.last.faults == (NONFINITE_ACTION,) and np.isfinite(target).all()


def test_a_goal_outside_the_workspace_is_reported_and_the_tcp_target_stays_inside(ur5e_reach):
    controller = Controller.from_export(ur5e_reach)
    q, _ = reset_at_home(controller)
    low, high = controller.workspace
    far = np.array([-2.0, 1.0, 1.5])  # beyond every face but one
    controller.policy = lambda inputs: np.ones(3)  # always as far as it goes
    T = controller.control_period
    for k in range(40):
        controller.act(q, np.zeros_like(q), goal=far, t=k * T, stamp=k * T)
        cycle = controller.last
        assert GOAL_OUTSIDE_WORKSPACE in cycle.faults
        tcp_target = cycle.ik_target[:3]
        assert (tcp_target >= low).all() and (tcp_target <= high).all()
        q = cycle.q_ik  # as if the arm got there
    assert "workspace_clip" in cycle.faults


def test_shapes_and_order_of_calls_are_checked(ur5e_reach):
    controller = Controller.from_export(ur5e_reach)
    with pytest.raises(InvalidConfig, match="reset"):
        controller.act(np.zeros(6), np.zeros(6), t=0.0)
    _q, _ = reset_at_home(controller)
    with pytest.raises(InvalidConfig, match="7 values; the contract's robot has 6 joints"):
        controller.act(np.zeros(7), np.zeros(7), t=0.0)
    with pytest.raises(InvalidConfig, match="goal has 4 values"):
        controller.set_goal(np.zeros(4))
    with pytest.raises(InvalidConfig, match="speed_scale"):
        ControllerOptions(speed_scale=2.0)


def test_the_runtime_imports_and_acts_without_torch_or_stable_baselines3(ur5e_reach):
    code = f"""
import sys
sys.modules["torch"] = None
sys.modules["stable_baselines3"] = None
import numpy as np
import tsrl.deploy, tsrl.deploy.cli, tsrl.deploy.loop
from tsrl.deploy.backends import MujocoBackend
from tsrl.deploy.controller import Controller
from tsrl.deploy.loop import run_episodes
c = Controller.from_export({str(ur5e_reach)!r})
results = run_episodes(c, MujocoBackend({str(ur5e_reach)!r}), [0])
assert len(results) == 1 and results[0].steps == 50
assert not any(m == "torch" or m.startswith(("torch.", "stable_baselines3")) for m in sys.modules if sys.modules[m])
print("ok")
"""
    out = subprocess.run(
        [sys.executable, "-c", code], check=False, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "ok"


def test_a_gripper_task_without_a_finite_width_holds(panda_pick_place_gripper):
    from tsrl.deploy.controller import MISSING_TOOL

    controller = Controller.from_export(panda_pick_place_gripper)
    env = exported_env(controller.folder, controller.contract)
    obs, _ = env.reset(seed=0)
    q, qd, objects, width = measured(env, controller)
    assert width is not None and 0 < width <= 0.08
    controller.reset(q, 0.0, obs["desired_goal"])
    for k, (bad, fault) in enumerate(((None, MISSING_TOOL), (float("nan"), NONFINITE_STATE)), start=1):
        controller.act(q, qd, objects, t=0.04 * k, tool=bad)
        assert controller.last.faults == (fault,) and controller.last.action is None
    controller.act(q, qd, objects, t=0.2, tool=width)
    assert controller.last.faults in ((), ("workspace_clip",)) and controller.tool is not None
