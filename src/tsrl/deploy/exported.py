"""An export folder's task, built the way training built it, from the folder's own copies.

The task is the folder's task.toml with its scene and robot replaced by the folder's model files and
robot.toml, with the run's observation and action (the contract's `task.env_kwargs`), exactly as
`gym.make` built the training environment. The controller uses its task-space interface
(`exported_interface`: step plan, goal, action map, IK); the MuJoCo backend uses a whole `TaskEnv`
(`exported_env`) as its simulated world. Nothing here imports torch or stable-baselines3.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from ..envs import TaskEnv, load_task
from ..envs.interface import TaskInterface
from ..envs.observations import OBS_PRESETS
from ..envs.scenes import load_scene
from ..envs.tasks import Task
from ..robots import load_robot
from .contract import ROBOT, TASK, Contract, ContractError

#: The limits every contract records for each controlled joint.
LIMIT_KEYS = ("max_joint_speed", "max_joint_acceleration")


def exported_env(folder: Path | str, contract: Contract, scene: Path | str | None = None) -> TaskEnv:
    """The run's environment from an export folder's copies (`scene`: another model file of the same
    arm instead of the exported scene, e.g. for a MuJoCo backend)."""
    task = _folder_task(folder, contract, scene)
    kwargs = contract.task.env_kwargs
    env = TaskEnv(task, obs=kwargs.obs, action=kwargs.action)
    check_env_matches(env, contract)
    return env


def exported_interface(folder: Path | str, contract: Contract) -> TaskInterface:
    """The run's task-space interface (step plan, goal, action map, IK) on the export's own model, as
    the training environment built it (its `ik_iterations` from the contract's IK options)."""
    kwargs = contract.task.env_kwargs
    task = _folder_task(folder, contract).with_overrides(kwargs.obs, kwargs.action, None)
    model = load_scene(task)
    robot = load_robot(task.robot_path).bind(model)
    iterations = contract.ik.options.max_iters if contract.ik is not None else 1
    interface = TaskInterface(
        task, model, robot, OBS_PRESETS.get(task.observation, task.observation), iterations
    )
    check_env_matches(interface, contract)
    return interface


def _folder_task(folder: Path | str, contract: Contract, scene: Path | str | None = None) -> Task:
    """The folder's task.toml with its scene (or `scene`) and robot the folder's copies."""
    folder = Path(folder).resolve()
    task = load_task(folder / TASK)
    scene_file = Path(scene).resolve() if scene is not None else folder / contract.task.scene
    return dataclasses.replace(task, scene=str(scene_file), robot=str(folder / ROBOT))


def check_env_matches(env: TaskEnv | TaskInterface, contract: Contract) -> None:
    """The environment has the contract's joints, control period, observation, goal and action.

    Raises:
        ContractError: one line naming what differs and what the contract says.
    """
    tool = contract.action.tool
    expected: list[tuple[str, Any, Any]] = [
        ("robot.joints", list(env.robot.joints), list(contract.robot.joints)),
        ("task.control_period_s", env.task.control_dt, contract.task.control_period_s),
        ("observation.spec", env.obs_map.spec, contract.observation.spec),
        ("observation.dim", env.obs_dim, contract.observation.dim),
        ("goal.dim", env.goal.dim, contract.goal.dim),
        ("action.dim", env.action_map.dim, contract.action.dim),
        ("action.tool.kind", _tool_kind(env), tool.kind if tool is not None else None),
    ]
    for key, actual, wanted in expected:
        if actual != wanted and not (isinstance(actual, float) and math.isclose(actual, wanted)):
            raise ContractError(
                f"contract.json: {key} is {wanted!r}, but the exported task builds {actual!r}"
            )


#: MjModel fields that say where its asset files were read from, not what the model is (MuJoCo 4
#: keeps each asset's absolute path; an export's copies live elsewhere), and the buffer size they add to.
_PATH_FIELDS = frozenset(
    {"paths", "npaths", "nbuffer", "mesh_pathadr", "skin_pathadr", "hfield_pathadr", "tex_pathadr"}
)


def model_difference(a: mujoco.MjModel, b: mujoco.MjModel) -> str | None:
    """The first field in which two compiled models differ (sizes, options, every array, names, bit for
    bit; NaN equal to NaN), or None when they are the same model; where asset files were read from is
    not compared (_PATH_FIELDS)."""
    for name in sorted(dir(a)):
        if name.startswith("_") or name in _PATH_FIELDS:
            continue
        x, y = getattr(a, name), getattr(b, name)
        if callable(x):
            continue
        if isinstance(x, np.ndarray):
            if (
                x.shape != y.shape
                or x.dtype != y.dtype
                or not np.array_equal(x, y, equal_nan=x.dtype.kind == "f")
            ):
                return name
        elif isinstance(x, int | float | bytes | str) and x != y:
            return name
    for group in ("opt", "vis", "stat"):
        if _struct_bytes(getattr(a, group)) != _struct_bytes(getattr(b, group)):
            return group
    return None


def _struct_bytes(struct: object) -> bytes:
    """A MuJoCo option/visual/statistic struct's contents, as the repr of its public fields."""
    return repr(
        [
            (k, np.asarray(v).tolist() if isinstance(v, np.ndarray) else repr(v))
            for k in sorted(dir(struct))
            if not k.startswith("_") and not callable(v := getattr(struct, k))
        ]
    ).encode()


def _tool_kind(env: TaskEnv | TaskInterface) -> str | None:
    """The action's tool dimension: "suction", "gripper" or None."""
    spec = env.action_map.spec
    return "suction" if spec.suction else "gripper" if spec.gripper else None
