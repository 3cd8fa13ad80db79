"""The export folder's contract: its file names, the description of every observation row, the
sha256 of every file, and reading a contract back with its files verified.

An export folder (`tsrl export RUN --out DIR`, tsrl.deploy.export)::

    DIR/contract.json   what the policy expects and what the controller enforces (CONTRACT_VERSION 1)
    DIR/policy.onnx     the deterministic actor, observation normaliser folded in
    DIR/task.toml       the task file the run trained on (a copy)
    DIR/robot.toml      the robot's names (joints, TCP, servos, suction)
    DIR/model/...       the scene's MJCF files (and those it includes), their layout kept

`contract.json` lists the sha256 of every other file; `read_contract` refuses a folder where one is
missing or differs, and a contract written by another major version of tsrl. Nothing here imports
torch or stable-baselines3.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..envs.observations import PREVIOUS_ACTIONS
from ..exceptions import InvalidConfig
from ..taskmaps import (
    AccumulatedCollisions,
    Distance,
    JointLimits,
    JointState,
    Position,
    PositionDiff,
    PositionRel,
    Quaternion,
    QuaternionDiff,
    ScalarProduct,
    Stack,
    Suction,
    TaskMap,
    Vector,
    Velocity,
)

CONTRACT = "contract.json"
POLICY = "policy.onnx"
TASK = "task.toml"
ROBOT = "robot.toml"
MODEL_DIR = "model"
#: The layout of contract.json; a reader refuses other layouts as it refuses other major versions.
CONTRACT_VERSION = 1
#: What `format` says in every contract.json.
FORMAT = "tsrl-deploy-contract"

_XYZ = ("x", "y", "z")
_WXYZ = ("w", "x", "y", "z")


class ContractError(InvalidConfig):
    """An export folder that cannot be used: a file missing or altered, a contract of another version."""


def sha256(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def major(version: str) -> int:
    """The major number of a version string "MAJOR.MINOR.PATCH"."""
    try:
        return int(str(version).split(".")[0])
    except ValueError:
        raise ContractError(f"version {version!r} is not MAJOR.MINOR.PATCH") from None


def describe_rows(stack: Stack, joint_units: Sequence[str] = ()) -> list[dict[str, Any]]:
    """One record per row of `stack`: index, map (its spec), component, frame the values are
    expressed in, unit. `joint_units` (rad or m per controlled joint) for joint maps."""
    rows: list[dict[str, Any]] = []
    for part in stack.parts:
        for component, frame, unit in _part_rows(part, tuple(joint_units)):
            rows.append(
                {"index": len(rows), "map": part.spec, "component": component, "frame": frame, "unit": unit}
            )
    return rows


def previous_action_rows(first: int, n: int, action_dim: int) -> list[dict[str, Any]]:
    """The records of the observation's last rows when the task observes its `n` previous actions
    (`Task.previous_actions`): indices from `first`, newest action first, each the policy's applied
    action in [-1, 1]."""
    return [
        {
            "index": first + j * action_dim + i,
            "map": PREVIOUS_ACTIONS,
            "component": f"action[{i}] at t-{j + 1}",
            "frame": "-",
            "unit": "1",
        }
        for j in range(n)
        for i in range(action_dim)
    ]


def _part_rows(part: TaskMap, joint_units: tuple[str, ...]) -> list[tuple[str, str, str]]:
    """(component, frame, unit) of each row of one map."""
    if isinstance(part, Velocity):
        return [(f"d/dt {c}", frame, f"{unit}/s") for c, frame, unit in _part_rows(part.map, joint_units)]
    if isinstance(part, Position | PositionDiff):
        return [(c, "world", "m") for c in _XYZ]
    if isinstance(part, PositionRel):
        return [(c, part.g.name, "m") for c in _XYZ]
    if isinstance(part, Quaternion | QuaternionDiff):
        return [(c, "world", "1") for c in _WXYZ]
    if isinstance(part, Vector):
        return [(c, "world", "1") for c in _XYZ]
    if isinstance(part, ScalarProduct):
        return [("value", "-", "1")]
    if isinstance(part, Distance | AccumulatedCollisions):
        return [("value", "-", "m")]
    if isinstance(part, Suction):
        return [("on", "-", "0/1"), ("holding", "-", "0/1")]
    if isinstance(part, JointState):
        return [(j, "joint", u) for j, u in zip(part.joints, _units(joint_units, len(part.joints)))]
    if isinstance(part, JointLimits):
        units = _units(joint_units, len(part.joints))
        return [(f"lower margin {j}", "joint", u) for j, u in zip(part.joints, units)] + [
            (f"upper margin {j}", "joint", u) for j, u in zip(part.joints, units)
        ]
    return [(f"row {i}", "unknown", "unknown") for i in range(part.dim)]  # a map tsrl does not describe


def _units(units: tuple[str, ...], n: int) -> tuple[str, ...]:
    return units if len(units) == n else ("rad",) * n


def read_contract(export_dir: Path | str) -> dict[str, Any]:
    """The contract of an export folder, after checking its version and every file's sha256.

    Raises:
        ContractError: no contract.json, not a tsrl contract, another major version of tsrl or
            another contract layout, a file it lists missing or with another sha256 (one line
            naming the file and what was expected).
    """
    from .. import __version__

    folder = Path(export_dir)
    path = folder / CONTRACT
    if not path.is_file():
        raise ContractError(f"{folder} is not an export folder: no {CONTRACT} (write one with `tsrl export`)")
    try:
        contract = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ContractError(f"{path}: not a readable JSON file ({err})") from None
    if not isinstance(contract, dict) or contract.get("format") != FORMAT:
        raise ContractError(f"{path}: not a tsrl deployment contract (format is not {FORMAT!r})")
    version = str(contract.get("tsrl_version"))
    if major(version) != major(__version__):
        raise ContractError(
            f"{path}: tsrl_version {version} (major {major(version)}); this tsrl is {__version__} "
            f"(major {major(__version__)}): export the run again with this version"
        )
    if contract.get("contract_version") != CONTRACT_VERSION:
        raise ContractError(
            f"{path}: contract_version {contract.get('contract_version')!r}; this tsrl reads {CONTRACT_VERSION}"
        )
    files = contract.get("files")
    if not isinstance(files, dict) or POLICY not in files:
        raise ContractError(f"{path}: 'files' must map every file of the export to its sha256")
    for name, expected in files.items():
        file = folder / name
        if not file.is_file():
            raise ContractError(f"{file}: missing; the contract lists it with sha256 {expected}")
        actual = sha256(file)
        if actual != expected:
            raise ContractError(f"{file}: sha256 {actual} differs from the contract's {expected}")
    return contract
