"""`tsrl export RUN --out DIR`: a run's policy as ONNX with its contract and copies of its files.

policy.onnx is the deterministic actor with the observation normaliser folded in: its inputs are the
raw observation-dict entries the actor reads (float64, as the environment emits them, batch first),
its output the action in [-1, 1] (float32). contract.json (tsrl.deploy.contract) describes
everything a robot must match. Before the folder is written whole (atomically), the export checks
itself: the copies compile to the training model byte for byte, and onnxruntime's actions equal the
torch policy's on observations of the task.

This module imports torch and stable-baselines3 (it reads a run); the runtime (tsrl.deploy's
Controller and backends) does not.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import shutil
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from .. import __version__
from ..agents.config import TrainConfig
from ..agents.evaluation import load_run_policy
from ..agents.factory import make_env
from ..agents.run_folder import CONFIG_FILE
from ..assets import SCENES, scene_path
from ..envs import TaskEnv
from ..exceptions import InvalidConfig
from ..files import replacing
from ..kinematics import joint_ids
from ..model_files import resolve_model_path
from ..taskmaps import Position, Stack
from .contract import (
    CONTRACT,
    CONTRACT_VERSION,
    FORMAT,
    MODEL_DIR,
    POLICY,
    ROBOT,
    TASK,
    Contract,
    check_normalizer_statistics,
    check_values,
    contract_digest,
    describe_rows,
    load_contract,
    previous_action_rows,
    sha256,
)
from .exported import exported_env, model_difference
from .limits import robot_limits

#: The largest difference between onnxruntime's and torch's actions an export accepts.
TOLERANCE = 1e-5
_OPSET = 17
_CHECK_STEPS = 200  # observations of the task the export compares the two policies on


class _Actor(th.nn.Module):
    """The SB3 actor's deterministic action of raw inputs: VecNormalize's rule, then the actor.

    Normalised input: clip((x - mean) / sqrt(var + eps), -clip, clip) in float64 (as VecNormalize
    computes it), cast to float32 (as SB3 casts observations); DDPG/TD3: the policy's deterministic
    action (the actor's tanh output; with a reference, the critic's choice, tsrl.agents.reference);
    SAC: tanh of the mean action (SB3's deterministic action).
    """

    def __init__(self, model: BaseAlgorithm, keys: tuple[str, ...], normalizer: VecNormalize | None):
        super().__init__()
        self.policy: Any = model.policy
        self.actor: Any = model.policy.actor  # an SB3 Actor (TD3/DDPG) or SAC Actor
        self.keys = keys
        self.sac = hasattr(self.actor, "get_action_dist_params")
        self.normalized = normalizer is not None
        self.clip = float(normalizer.clip_obs) if normalizer is not None else 0.0
        for i, key in enumerate(keys):
            if normalizer is not None:
                rms = normalizer.obs_rms[key]
                std = np.sqrt(rms.var + normalizer.epsilon)
                self.register_buffer(f"mean_{i}", th.as_tensor(np.asarray(rms.mean, np.float64)))
                self.register_buffer(f"std_{i}", th.as_tensor(np.asarray(std, np.float64)))

    def forward(self, *inputs: th.Tensor) -> th.Tensor:
        obs = {}
        for i, (key, x) in enumerate(zip(self.keys, inputs)):
            if self.normalized:
                x = ((x - getattr(self, f"mean_{i}")) / getattr(self, f"std_{i}")).clamp(
                    -self.clip, self.clip
                )
            obs[key] = x.float()
        if self.sac:
            mean_actions, _, _ = self.actor.get_action_dist_params(obs)
            return th.tanh(mean_actions)
        return self.policy._predict(obs, deterministic=True)


def export_run(
    run_dir: Path | str,
    out: Path | str,
    max_joint_speed: tuple[float, ...] | None = None,
    max_joint_acceleration: tuple[float, ...] | None = None,
) -> Path:
    """Exports the newest usable checkpoint of a run folder into `out` (replaced whole); returns `out`.

    `max_joint_speed` [rad/s] and `max_joint_acceleration` [rad/s^2] (one value, or one per joint)
    override the built-in robot's limits; a robot that is not built in needs both.
    """
    run_dir = Path(run_dir)
    check_out(out, run_dir)
    cfg, model, normalizer, checkpoint = load_run_policy(run_dir)
    run = {
        "dir": str(run_dir.resolve()),
        "checkpoint": checkpoint.path.name,
        "env_steps": checkpoint.state.env_steps,
        "config": cfg.to_dict(),
    }
    return export_policy(model, normalizer, cfg, out, run, max_joint_speed, max_joint_acceleration)


def export_policy(
    model: BaseAlgorithm,
    normalizer: VecNormalize | None,
    cfg: TrainConfig,
    out: Path | str,
    run: dict[str, Any] | None = None,
    max_joint_speed: tuple[float, ...] | None = None,
    max_joint_acceleration: tuple[float, ...] | None = None,
) -> Path:
    """Exports `model` (trained with `cfg`, its normaliser `normalizer`) into `out` (module docstring)."""
    out = Path(out)
    check_out(out, Path(run["dir"]) if run else None)
    if not cfg.is_tsrl_env:
        raise InvalidConfig(f"tsrl export needs a tsrl environment; the run trained on {cfg.env_id!r}")
    env = make_env(cfg).unwrapped
    assert isinstance(env, TaskEnv)
    task = env.task
    if task.obstacle is not None:
        raise InvalidConfig(
            f"task {task.name!r} has an obstacle whose size is drawn per episode; no robot backend measures "
            "it, so obstacle tasks cannot be exported for deployment"
        )
    if task.fixtures:  # placed at goal + offset by the Randomizer; the controller would need that rule
        raise InvalidConfig(
            f"task {task.name!r} places fixtures ({', '.join(f.body for f in task.fixtures)}) with the goal each "
            "episode; no robot backend measures them, so it cannot be exported for deployment"
        )
    if task.source is None:
        raise InvalidConfig(f"task {task.name!r} was built in code; export needs a task file")
    keys = tuple(cfg.agent.policy_inputs)
    if normalizer is not None:
        for key in keys:
            rms = normalizer.obs_rms[key]
            check_normalizer_statistics("the run's vecnormalize.pkl", key, rms.mean, rms.var, rms.count)
    limits = robot_limits(task.robot, len(env.robot.joints), max_joint_speed, max_joint_acceleration)
    out.parent.mkdir(parents=True, exist_ok=True)
    with replacing(out) as tmp:
        tmp.mkdir()
        _write_onnx(_Actor(model, keys, normalizer).eval(), env, keys, tmp / POLICY)
        shutil.copyfile(task.source, tmp / TASK)
        scene = _copy_model_files(_scene_file(task), tmp)
        (tmp / ROBOT).write_text(_robot_toml(env, scene))
        contract = _contract(env, cfg, keys, normalizer, limits, scene, run)
        contract["files"] = {
            str(p.relative_to(tmp)): sha256(p) for p in sorted(tmp.rglob("*")) if p.is_file()
        }
        contract = json.loads(json.dumps(contract))  # as a reader will see it
        contract["sha256"] = contract_digest(contract)
        check_values(contract, f"the export of {task.name!r}")
        record = load_contract(contract, f"the export of {task.name!r}")  # as read_contract reads it
        (tmp / CONTRACT).write_text(contract_text(contract))
        _check(tmp, record, env, model, normalizer, keys)
    env.close()
    return out


def check_out(out: Path | str, run_dir: Path | None = None) -> None:
    """Raises InvalidConfig (nothing is deleted) unless `out` may be replaced by an export: absent, an
    empty folder, or a folder an export wrote (its contract.json and the files it lists, nothing
    else). A run folder, a folder holding `run_dir` or any run (a child with config.json), a file and
    any other non-empty folder are refused."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InvalidConfig(f"--out {out} is a file; give a new folder or an earlier export's")
    if run_dir is not None:
        run = run_dir.resolve()
        if out.resolve() == run or out.resolve() in run.parents:
            raise InvalidConfig(f"--out {out} holds the run {run_dir}; an export replaces its folder whole")
    if not out.is_dir():
        return
    if (out / CONFIG_FILE).is_file():
        raise InvalidConfig(f"--out {out} is a run folder; an export replaces its folder whole")
    runs = sorted(c.name for c in out.iterdir() if (c / CONFIG_FILE).is_file())
    if runs:
        raise InvalidConfig(f"--out {out} holds runs ({runs[0]}, ...); an export replaces its folder whole")
    if any(out.iterdir()) and not _written_by_export(out):
        raise InvalidConfig(
            f"--out {out} is a non-empty folder that `tsrl export` did not write; give a new or empty folder"
        )


def _written_by_export(folder: Path) -> bool:
    """Whether `folder` holds an export's contract.json and the files it lists, and nothing else."""
    try:
        contract = json.loads((folder / CONTRACT).read_text())
        listed = {CONTRACT, *contract["files"]}
    except (OSError, ValueError, KeyError, TypeError):
        return False
    if not isinstance(contract, dict) or contract.get("format") != FORMAT:
        return False
    present = {str(p.relative_to(folder)) for p in folder.rglob("*") if not p.is_dir()}
    return present <= listed


def contract_text(contract: dict[str, Any]) -> str:
    """contract.json's text: indented, each list of numbers or names on one line."""
    text = json.dumps(contract, indent=2)
    flat = re.compile(
        r"\[\s*((?:-?[\d.eE+-]+|null|true|false|\"[^\"\n]*\")(?:,\s*(?:-?[\d.eE+-]+|null|true|false|\"[^\"\n]*\"))*)\s*\]"
    )
    return flat.sub(lambda m: "[" + ", ".join(v.strip() for v in m.group(1).split(",\n")) + "]", text) + "\n"


def _write_onnx(actor: _Actor, env: TaskEnv, keys: tuple[str, ...], path: Path) -> None:
    dims = input_dims(env)
    example = tuple(th.zeros((1, dims[k]), dtype=th.float64) for k in keys)
    axes = {k: {0: "batch"} for k in keys} | {"action": {0: "batch"}}
    with warnings.catch_warnings():
        # The TorchScript exporter (dynamo=False) needs no onnxscript; torch 2.13 marks it deprecated.
        warnings.simplefilter("ignore", category=DeprecationWarning)
        th.onnx.export(
            actor,
            example,
            str(path),
            input_names=list(keys),
            output_names=["action"],
            dynamic_axes=axes,
            opset_version=_OPSET,
            dynamo=False,
        )


def input_dims(env: TaskEnv) -> dict[str, int]:
    """The size of each observation-dict entry of the environment."""
    return {"observation": env.obs_dim, "achieved_goal": env.goal.dim, "desired_goal": env.goal.dim}


def torch_actions(
    model: BaseAlgorithm, normalizer: VecNormalize | None, observations: dict[str, np.ndarray]
) -> np.ndarray:
    """The run's deterministic actions (B, k) of raw observation dicts (batched), as `tsrl evaluate`
    computes them."""
    batch = normalizer.normalize_obs(observations) if normalizer is not None else observations
    actions, _ = model.predict(batch, deterministic=True)
    return np.asarray(actions)


def task_observations(env: TaskEnv, n: int, seed: int = 0) -> dict[str, np.ndarray]:
    """n raw observation dicts (batched, (n, d) each) of the task under uniformly random actions."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, np.ndarray]] = []
    episode = 0
    obs, _ = env.reset(seed=seed)
    while len(rows) < n:
        rows.append(obs)
        obs, _, terminated, truncated, _ = env.step(rng.uniform(-1, 1, env.action_space.shape))
        if terminated or truncated:
            episode += 1
            obs, _ = env.reset(seed=seed + episode)
    return {k: np.stack([r[k] for r in rows]) for k in rows[0]}


def _check(
    folder: Path,
    contract: Contract,
    env: TaskEnv,
    model: BaseAlgorithm,
    normalizer: VecNormalize | None,
    keys: tuple[str, ...],
) -> None:
    """The copies build the training model byte for byte; onnxruntime's actions equal torch's."""
    from .policy import OnnxPolicy

    again = exported_env(folder, contract)
    differs = model_difference(again.model, env.model)
    if differs is not None:
        raise InvalidConfig(
            f"the copies of {contract.task.scene} compile to another model than the training scene "
            f"(its {differs} differs: a file it reads was not copied); give the task a scene whose files "
            "are named in its MJCF (includes, meshdir/texturedir)"
        )
    again.close()
    observations = task_observations(env, _CHECK_STEPS)
    expected = torch_actions(model, normalizer, observations)
    actual = OnnxPolicy(folder / POLICY, keys).batch({k: observations[k] for k in keys})
    error = float(np.max(np.abs(actual - expected)))
    if not error <= TOLERANCE:
        raise InvalidConfig(f"policy.onnx differs from the torch policy by {error:.3g} (> {TOLERANCE:g})")


def _scene_file(task: Any) -> Path:
    if task.scene in SCENES:
        return scene_path(task.scene)
    return resolve_model_path(task.scene, task.source.parent if task.source else None, key="scene")


def model_files(main: Path) -> list[Path]:
    """The model file and every file it reads: MJCF includes (recursively, relative to the main file's
    folder) and asset files (meshdir / texturedir / assetdir of <compiler>); a URDF's mesh files."""
    main = main.resolve()
    base = main.parent
    files, queue, elements = [main], [main], []
    while queue:
        root = ET.parse(queue.pop()).getroot()
        for el in root.iter():
            name = el.get("file") or (el.get("filename") if el.tag == "mesh" else None)
            if el.tag == "include" and name:
                path = (base / name).resolve()
                if path not in files:
                    files.append(path)
                    queue.append(path)
            elif name:
                elements.append(el)
    dirs: dict[str, str] = {}
    for path in files:
        if path.suffix.lower() == ".xml":
            for compiler in ET.parse(path).getroot().iter("compiler"):
                dirs.update(
                    {k: v for k, v in compiler.attrib.items() if k in ("meshdir", "texturedir", "assetdir")}
                )
    for el in elements:
        name = el.get("file") or el.get("filename") or ""
        if name.startswith("package://"):
            raise InvalidConfig(f"{main}: asset {name!r} is a ROS package path; give the file's path")
        kind = "meshdir" if el.tag in ("mesh", "skin") else "texturedir"
        folder = dirs.get(kind, dirs.get("assetdir", ""))
        path = (base / folder / name).resolve()
        if path not in files:
            files.append(path)
    return files


def _copy_model_files(main: Path, out: Path) -> str:
    """Copies the model files under out/model/, their layout relative to each other kept; returns the
    main file's path relative to `out`."""
    files = model_files(main)
    root = Path(os.path.commonpath([f.parent for f in files]))
    for f in files:
        dest = out / MODEL_DIR / f.relative_to(root)
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(f, dest)
    return str(Path(MODEL_DIR) / main.resolve().relative_to(root))


def _robot_toml(env: TaskEnv, scene: str) -> str:
    """The robot's description as TOML, its model the exported scene (which holds the arm)."""
    robot = dataclasses.replace(env.robot, model=scene)
    lines = [f"# The robot of the exported task ({env.robot.name}); its model is the exported scene."]
    for f in dataclasses.fields(robot):
        value = getattr(robot, f.name)
        if value is None or value == ():
            continue
        lines.append(f"{f.name} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string is a JSON string
    if isinstance(value, int | float):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise InvalidConfig(f"robot field value {value!r} cannot be written to robot.toml")


def _joint_limits(env: TaskEnv) -> np.ndarray:
    """The joints' position limits (n, 2): each joint's range, or for a joint without one (an unlimited
    hinge), its servo's control range (tsrl gives an added servo +-2 pi: docs/robots.md), which no
    command of the training environment left either."""
    robot, m = env.bound_robot, env.model
    limits = np.array(robot.joint_range, dtype=np.float64)
    for i, ctrl in enumerate(np.arange(m.nu)[robot.ctrl]):
        if not np.isfinite(limits[i]).all() and m.actuator_ctrllimited[ctrl]:
            limits[i] = m.actuator_ctrlrange[ctrl]
    return limits


def _tool(env: TaskEnv) -> dict[str, Any] | None:
    """The contract's tool command: the action column, the actuator and the rule from action to its
    control value (TaskInterface.tool), or None without a tool dimension."""
    interface, spec = env.interface, env.action_map.spec
    if interface.tool_ctrl is None:
        return None
    entry: dict[str, Any] = {
        "column": env.action_map.dim - 1,
        "actuator": env.model.actuator(interface.tool_ctrl).name,
    }
    if spec.suction:
        return entry | {"kind": "suction", "rule": "1 (on) if a > 0 else 0 (off)"}
    low, high = (float(v) for v in env.model.actuator_ctrlrange[interface.tool_ctrl])
    rule = "high if a > 0 else low" if spec.gripper_open_close else "low + (a + 1) / 2 (high - low)"
    return entry | {
        "kind": "gripper",
        "rule": rule,
        "width_range_m": [low, high],
        "measured": "the opening width [m] (gripperWidth of the actuator), RobotState.tool",
    }


def _contract(
    env: TaskEnv,
    cfg: TrainConfig,
    keys: tuple[str, ...],
    normalizer: VecNormalize | None,
    limits: dict[str, object],
    scene: str,
    run: dict[str, Any] | None,
) -> dict[str, Any]:
    task, robot, m = env.task, env.robot, env.model
    ids = joint_ids(m, robot.joints)
    joint_units = ["m" if int(m.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE) else "rad" for j in ids]
    tcp_site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, robot.tcp)
    base_body = int(m.body_parentid[m.jnt_bodyid[ids[0]]])
    data = mujoco.MjData(m)
    mujoco.mj_kinematics(m, data)
    action = env.action_map
    ik_map = action.ik_map
    parts, col = [], 0
    workspace = None
    for index, (part, ik_part) in enumerate(zip(action.spec.parts, ik_map.parts if ik_map else ())):
        entry: dict[str, Any] = {"map": part.map, "columns": [col, col + ik_part.dim]}
        entry |= {"step": part.step} if part.step is not None else {}
        entry |= (
            {"center": list(part.center), "half_range": list(part.half_range)} if part.step is None else {}
        )
        entry |= {"low": list(part.low), "high": list(part.high)} if part.low or part.high else {}
        parts.append(entry)
        col += ik_part.dim
        if isinstance(ik_part, Position) and ik_part.f.name == robot.tcp and part.low and part.high:
            workspace = {
                "part": index,  # the action part that sets the TCP position target
                "low": list(part.low),
                "high": list(part.high),
                "frame": "world",
                "unit": "m",
            }
    goal_rows = describe_rows(Stack([*env.goal.achieved_maps, *env.goal.penalty_maps]), joint_units)
    return {
        "format": FORMAT,
        "contract_version": CONTRACT_VERSION,
        "tsrl_version": __version__,
        "frames": (
            "every position and orientation is in the scene's world frame unless a row says otherwise"
            + (
                "; the task expresses the scene in the robot's base frame: world = base"
                if task.frame == "base"
                else ""
            )
        ),
        "robot": {
            "name": robot.name,
            "joints": list(robot.joints),
            "joint_units": joint_units,
            "joint_limits": _joint_limits(env).tolist(),
            "home_q": robot.home_q(m).tolist(),
            "tcp": {
                "frame": robot.tcp,
                "body": m.body(m.site_bodyid[tcp_site]).name if tcp_site >= 0 else robot.tcp,
                "pos_in_body_m": m.site_pos[tcp_site].tolist() if tcp_site >= 0 else [0.0, 0.0, 0.0],
                "quat_in_body_wxyz": m.site_quat[tcp_site].tolist()
                if tcp_site >= 0
                else [1.0, 0.0, 0.0, 0.0],
            },
            "base_frame": {
                "body": m.body(base_body).name,
                "pos_in_world_m": data.xpos[base_body].tolist(),
                "quat_in_world_wxyz": data.xquat[base_body].tolist(),
            },
            "actuators": list(robot.actuators),
            "suction": robot.suction,
            **limits,
        },
        "task": {
            "name": task.name,
            "frame": task.frame,
            "file": TASK,
            "scene": scene,
            "robot_file": ROBOT,
            "env_kwargs": {"obs": cfg.obs, "action": cfg.env_kwargs.get("action")},
            "control_period_s": task.control_dt,
            "physics_timestep_s": float(m.opt.timestep),
            "episode_steps": task.episode_steps,
            "objects": [
                {
                    "body": o.body,
                    "state": "pos (3) m, quat (4) wxyz; optional free-joint qvel (6): linear m/s "
                    "in world, angular rad/s in the body frame",
                }
                for o in task.objects
            ],
        },
        "observation": {
            "spec": env.obs_map.spec,
            "dim": env.obs_dim,
            "previous_actions": task.previous_actions,
            "rows": describe_rows(env.obs_map, joint_units)
            + previous_action_rows(env.obs_map.dim, task.previous_actions, action.dim),
        },
        "goal": {
            "map": task.goal.map,
            "dim": env.goal.dim,
            "rows": goal_rows,
            "markers": [p.marker for p in env.goal.parts],
            "tolerances": {"position_m": task.success.position, "orientation_deg": task.success.orientation},
            "reward": task.success.reward,
            "sampler": dataclasses.asdict(task.goal),
        },
        "action": {
            "dim": action.dim,
            "mode": env.action_mode,
            "range": [-1.0, 1.0],
            "parts": parts,
            "hold": [{"map": h.map, "value": list(h.value)} for h in action.spec.hold],
            "suction": {"column": action.dim - 1, "on_above": 0.0} if action.spec.suction else None,
            "tool": _tool(env),
            "joint_step_rad": None if action.spec.uses_ik else action.spec.joint_step,
        },
        "workspace": workspace,
        "ik": None if ik_map is None else {"map": ik_map.spec, "options": dataclasses.asdict(env.ik_options)},
        "policy": {
            "file": POLICY,
            "algo": cfg.agent.algo,
            "inputs": [{"name": k, "dim": input_dims(env)[k], "dtype": "float64"} for k in keys],
            "output": {"name": "action", "dim": action.dim, "dtype": "float32", "range": [-1.0, 1.0]},
            "normalizer": None
            if normalizer is None
            else {
                "applied": "inside policy.onnx: feed raw values",
                "rule": "clip((x - mean) / sqrt(var + epsilon), -clip, clip)",
                "epsilon": float(normalizer.epsilon),
                "clip": float(normalizer.clip_obs),
                "statistics": {
                    k: {
                        "mean": np.asarray(normalizer.obs_rms[k].mean).tolist(),
                        "var": np.asarray(normalizer.obs_rms[k].var).tolist(),
                        "count": float(normalizer.obs_rms[k].count),
                    }
                    for k in keys
                },
            },
        },
        "run": run,
    }
