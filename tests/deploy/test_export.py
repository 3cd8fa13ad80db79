"""tsrl export: policy.onnx equals the torch policy (normaliser folded in) on 1,000 observations of the
task for DDPG, TD3 and SAC; the contract describes every row, file and limit; the copies build the
training model."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import build_export

from tsrl.deploy.contract import CONTRACT, POLICY, read_contract, sha256
from tsrl.deploy.export import TOLERANCE, task_observations, torch_actions
from tsrl.deploy.exported import exported_env, model_difference
from tsrl.deploy.policy import OnnxPolicy


@pytest.mark.parametrize("algo", ["ddpg", "td3", "sac"])
def test_onnx_actions_equal_the_torch_policy_on_1000_observations(algo, tmp_path):
    out, model, normalizer, _ = build_export(tmp_path / "export", algo=algo, seed=3)
    contract = read_contract(out)
    env = exported_env(out, contract)
    observations = task_observations(env, 1000, seed=7)
    keys = tuple(i.name for i in contract.policy.inputs)
    policy = OnnxPolicy(out / POLICY, keys)
    onnx = policy.batch(observations)
    torch = torch_actions(model, normalizer, observations)
    assert onnx.shape == torch.shape == (1000, env.action_space.shape[0])
    np.testing.assert_allclose(onnx, torch, rtol=0, atol=TOLERANCE)
    assert onnx.std(axis=0).min() > 1e-3  # the actions vary: the comparison can fail
    # The normaliser is folded in: the raw inputs give the torch policy's actions of normalised inputs,
    # which differ from its actions of the raw inputs.
    raw = torch_actions(model, None, observations)
    assert np.abs(raw - onnx).max() > 100 * TOLERANCE
    # One observation at a time (the controller's call) gives the same actions.
    one = np.stack([policy({k: observations[k][i] for k in keys}) for i in range(20)])
    np.testing.assert_allclose(one, onnx[:20], rtol=0, atol=1e-7)


def test_the_contract_describes_the_rows_files_limits_and_normaliser(ur5e_reach):
    contract = json.loads((ur5e_reach / CONTRACT).read_text())  # the file's own layout
    env = exported_env(ur5e_reach, read_contract(ur5e_reach))
    assert contract["robot"]["joints"] == list(env.robot.joints)
    assert contract["robot"]["max_joint_speed"] == [np.pi] * 6
    rows = contract["observation"]["rows"]
    assert len(rows) == env.obs_map.dim == contract["observation"]["dim"] == 15
    assert rows[0] == {"index": 0, "map": "position(tcp)", "component": "x", "frame": "world", "unit": "m"}
    assert rows[9]["map"] == "velocity(position(tcp))" and rows[9]["unit"] == "m/s"
    assert [r["map"] for r in contract["goal"]["rows"]] == ["position(tcp)"] * 3
    assert contract["goal"]["tolerances"]["position_m"] == 0.05
    assert contract["action"]["parts"][0] == {
        "map": "position(tcp)",
        "columns": [0, 3],
        "step": 0.05,
        "low": [-0.9, -0.55, 0.02],
        "high": [-0.15, 0.3, 0.7],
    }
    assert contract["action"]["hold"] == [{"map": "vectorZ(tcp)", "value": [0.0, 0.0, -1.0]}]
    assert contract["workspace"]["low"] == [-0.9, -0.55, 0.02] and contract["workspace"]["part"] == 0
    assert contract["task"]["control_period_s"] == 0.04
    # The IK options are the env's own.
    assert contract["ik"]["options"]["max_iters"] == 1 and contract["ik"]["options"]["restarts"] == 0
    # Every file but the contract itself, with its sha256.
    files = {str(p.relative_to(ur5e_reach)) for p in ur5e_reach.rglob("*") if p.is_file()} - {CONTRACT}
    assert set(contract["files"]) == files
    assert {
        "policy.onnx",
        "task.toml",
        "robot.toml",
        "model/scenes/reach.xml",
        "model/ur5e/ur5e.xml",
    } <= files
    assert all(sha256(ur5e_reach / f) == h for f, h in contract["files"].items())
    stats = contract["policy"]["normalizer"]["statistics"]
    assert set(stats) == {"observation", "achieved_goal", "desired_goal"}
    assert len(stats["observation"]["mean"]) == 15


def test_the_contract_is_read_as_a_typed_frozen_record(ur5e_reach):
    import dataclasses

    from tsrl.deploy.contract import ActionPart, Contract, Row
    from tsrl.ik.options import IKOptions

    record = read_contract(ur5e_reach)
    assert isinstance(record, Contract)
    assert record.robot.max_joint_speed == (np.pi,) * 6 and record.robot.joint_limits[0][0] < 0
    assert record.observation.rows[0] == Row(0, "position(tcp)", "x", "world", "m")
    assert record.action.parts[0] == ActionPart(
        "position(tcp)", (0, 3), step=0.05, low=(-0.9, -0.55, 0.02), high=(-0.15, 0.3, 0.7)
    )
    assert record.workspace is not None and record.workspace.part == 0
    assert isinstance(record.ik.options, IKOptions) and record.ik.options.max_iters == 1
    assert record.policy.normalizer is not None
    assert len(record.policy.normalizer.statistics["observation"].mean) == record.observation.dim == 15
    assert record.task.episode_steps == 50 and record.action.tool is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        record.robot.joints = ()  # type: ignore[misc]
    with pytest.raises(TypeError):
        record.files["policy.onnx"] = "0" * 64  # type: ignore[index]
    # Code written against the JSON dict reads it as before.
    assert record["robot"]["joints"] == record.robot.joints and record.get("workspace") is record.workspace


def test_the_copies_compile_to_the_training_model(ur5e_reach, panda_pick_place):
    import gymnasium as gym

    for folder, env_id, obs in (
        (ur5e_reach, "tsrl/UR5eReach-v0", "fs1"),
        (panda_pick_place, "tsrl/PandaPickPlace-v0", "pick_phi_plus"),
    ):
        exported = exported_env(folder, read_contract(folder))
        trained = gym.make(env_id, obs=obs, action="taskspace").unwrapped
        assert model_difference(exported.model, trained.model) is None
        assert exported.obs_map.spec == trained.obs_map.spec


def test_a_policy_that_sees_fewer_inputs_exports_only_those(tmp_path):
    out, *_ = build_export(tmp_path / "export", policy_inputs=("observation", "desired_goal"))
    contract = read_contract(out)
    assert [i.name for i in contract.policy.inputs] == ["observation", "desired_goal"]
    OnnxPolicy(out / POLICY, ("observation", "desired_goal"))  # the file's inputs are those


@pytest.mark.parametrize(
    ("env_id", "why"),
    [
        ("tsrl/UR5eObstacleReach-v1", "obstacle whose size is drawn"),
        ("tsrl/PandaPegInsert-v0", "places fixtures"),
    ],
)
def test_tasks_the_runtime_cannot_measure_are_refused_in_one_line(env_id, why, tmp_path):
    from tsrl.exceptions import InvalidConfig

    with pytest.raises(InvalidConfig, match=why) as err:
        build_export(tmp_path / "export", env_id=env_id, obs="fs1")
    assert "\n" not in str(err.value)
    assert not (tmp_path / "export").exists()


def test_a_task_that_observes_its_previous_actions_exports_them_as_the_last_rows(ur5e_reach_history):
    from tsrl.deploy.contract import read_contract
    from tsrl.envs.observations import PREVIOUS_ACTIONS

    contract = read_contract(ur5e_reach_history)
    observation, k = contract.observation, contract.action.dim
    rows = observation.rows
    assert observation.previous_actions == 2
    [policy_input] = [i for i in contract.policy.inputs if i.name == "observation"]
    assert observation.dim == len(rows) == policy_input.dim
    history = [r for r in rows if r.map == PREVIOUS_ACTIONS]
    assert [r.index for r in history] == list(range(len(rows) - 2 * k, len(rows)))
    assert history[0].component == "action[0] at t-1"
    assert history[-1].component == f"action[{k - 1}] at t-2"
