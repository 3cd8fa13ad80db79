"""An arm built from mesh files (Gymnasium-Robotics' Fetch, examples/robots/) exports and deploys: the
export compares what the copied model is, not where its files were (MuJoCo keeps asset paths)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import mujoco
import numpy as np
import pytest

from tsrl.deploy import Controller, ControllerOptions
from tsrl.deploy.backends import MujocoBackend
from tsrl.deploy.contract import read_contract
from tsrl.deploy.exported import exported_env, model_difference
from tsrl.deploy.loop import run_episodes
from tsrl.envs import TASK_ENV_ID

FETCH_REACH = Path(__file__).parents[2] / "examples" / "robots" / "fetch_reach.toml"

pytestmark = [
    pytest.mark.filterwarnings("ignore::tsrl.robot_model.RobotNotice"),
    pytest.mark.skipif(
        importlib.util.find_spec("gymnasium_robotics") is None,
        reason="the Fetch arm's model ships with gymnasium-robotics (in the dev extra)",
    ),
]


@pytest.fixture(scope="module")
def fetch_export(exports) -> Path:
    return exports("fetch_reach", env_id=str(FETCH_REACH), obs="", limits=((2.0,), (10.0,)))


def test_a_mesh_arm_exports_its_meshes_and_compiles_to_the_training_model(fetch_export):
    import gymnasium as gym

    meshes = sorted(p.name for p in (fetch_export / "model").rglob("*.stl"))
    assert "shoulder_pan_link_collision.stl" in meshes and len(meshes) > 10
    contract = read_contract(fetch_export)
    # the unlimited roll joints are bounded by their servos' range (+-2 pi), as in training
    limits = np.array(contract.robot.joint_limits)
    assert np.isfinite(limits).all() and np.allclose(limits[2], [-2 * np.pi, 2 * np.pi])
    exported = exported_env(fetch_export, contract)
    trained = gym.make(TASK_ENV_ID, task=str(FETCH_REACH)).unwrapped
    assert model_difference(exported.model, trained.model) is None


def test_model_difference_names_what_the_model_is_not_where_it_was_read(fetch_export):
    contract = read_contract(fetch_export)
    a, b = (exported_env(fetch_export, contract).model for _ in range(2))
    assert model_difference(a, b) is None
    mesh = mujoco.mj_name2id(a, mujoco.mjtObj.mjOBJ_MESH, "robot0:shoulder_pan_link")
    assert mesh >= 0
    b.mesh_vert[a.mesh_vertadr[mesh]] += 1e-3  # one vertex of one mesh, 1 mm (float32)
    assert model_difference(a, b) == "mesh_vert"
    b.mesh_vert[:] = a.mesh_vert
    b.opt.timestep = 0.001
    assert model_difference(a, b) == "opt"


def test_a_mesh_arm_deploys_on_the_stand_in(fetch_export):
    backend = MujocoBackend(fetch_export, seed=0)
    controller = Controller.from_export(fetch_export, ControllerOptions(servo_period=backend.period))
    env = exported_env(fetch_export, controller.contract)
    obs, _ = env.reset(seed=3)
    goal = controller.sample_goal(3)
    np.testing.assert_array_equal(goal, obs["desired_goal"])  # the goal `tsrl evaluate` draws
    (result,) = run_episodes(controller, backend, [3], servo="hold")
    assert result.steps == 50 and np.isfinite(result.distance)
    assert set(result.faults) <= {"workspace_clip", "joint_limit"}
