"""The export folder's contract: its file names, the description of every observation row, the
sha256 of every file, and reading a contract back with its files verified.

An export folder (`tsrl export RUN --out DIR`, tsrl.deploy.export)::

    DIR/contract.json   what the policy expects and what the controller enforces (CONTRACT_VERSION 2)
    DIR/policy.onnx     the deterministic actor, observation normaliser folded in
    DIR/task.toml       the task file the run trained on (a copy)
    DIR/robot.toml      the robot's names (joints, TCP, servos, suction)
    DIR/model/...       the scene's MJCF files (and those it includes), their layout kept

`contract.json` lists the sha256 of every other file and carries its own (`sha256`: of its other
keys, written canonically: `contract_digest`); `read_contract` refuses a folder where a file is
missing or differs, an altered contract, a contract written by another major version of tsrl, and
limits or normaliser statistics a safety layer or a policy cannot use (`check_values`: finite,
positive, ordered), and returns the contract as a typed, frozen record (`Contract`, built by the
project's one loader, tsrl.configs: every key and type checked, one line naming the file and key).
Nothing here imports torch or stable-baselines3.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Literal

from ..configs import load_table
from ..envs.observations import PREVIOUS_ACTIONS
from ..exceptions import InvalidConfig
from ..ik.options import IKOptions
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
#: 2: the contract's own sha256, the action's tool.
CONTRACT_VERSION = 2
#: What `format` says in every contract.json.
FORMAT = "tsrl-deploy-contract"

_XYZ = ("x", "y", "z")
_WXYZ = ("w", "x", "y", "z")


class ContractError(InvalidConfig):
    """An export folder that cannot be used: a file missing or altered, a contract of another version."""


class Record:
    """A part of the contract. Its fields are the contract.json keys; `record["key"]` and
    `record.get("key")` read them as the JSON dict did (for code written against the dict)."""

    __dataclass_fields__: ClassVar[dict[str, Any]]

    def __getitem__(self, key: str) -> Any:
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def get(self, key: str, default: Any = None) -> Any:
        return getattr(self, key) if key in self.__dataclass_fields__ else default


@dataclass(frozen=True)
class TcpFrame(Record):
    frame: str
    body: str
    pos_in_body_m: tuple[float, float, float]
    quat_in_body_wxyz: tuple[float, float, float, float]


@dataclass(frozen=True)
class BaseFrame(Record):
    body: str
    pos_in_world_m: tuple[float, float, float]
    quat_in_world_wxyz: tuple[float, float, float, float]


@dataclass(frozen=True)
class ContractRobot(Record):
    """The arm: joints (in the order of every joint vector), units, limits the safety layer enforces."""

    name: str
    joints: tuple[str, ...]
    joint_units: tuple[str, ...]
    joint_limits: tuple[tuple[float, float], ...]
    """[lower, upper] per joint [rad or m]."""
    home_q: tuple[float, ...]
    tcp: TcpFrame
    base_frame: BaseFrame
    actuators: tuple[str, ...]
    suction: str | None
    max_joint_speed: tuple[float, ...]
    max_joint_acceleration: tuple[float, ...]
    limits_source: str


@dataclass(frozen=True)
class EnvKwargs(Record):
    obs: str
    action: str | None


@dataclass(frozen=True)
class ContractObject(Record):
    body: str
    state: str


@dataclass(frozen=True)
class ContractTask(Record):
    name: str
    frame: Literal["world", "base"]
    file: str
    scene: str
    """The scene's MJCF file, relative to the export folder."""
    robot_file: str
    env_kwargs: EnvKwargs
    control_period_s: float
    physics_timestep_s: float
    episode_steps: int
    objects: tuple[ContractObject, ...]


@dataclass(frozen=True)
class Row(Record):
    """One row of the observation or the goal: its index, map, component, frame and unit."""

    index: int
    map: str
    component: str
    frame: str
    unit: str


@dataclass(frozen=True)
class ContractObservation(Record):
    spec: str
    dim: int
    previous_actions: int
    rows: tuple[Row, ...]


@dataclass(frozen=True)
class Tolerances(Record):
    position_m: float | None
    orientation_deg: float | None


@dataclass(frozen=True)
class ContractGoal(Record):
    map: str
    dim: int
    rows: tuple[Row, ...]
    markers: tuple[str, ...]
    tolerances: Tolerances
    reward: str
    sampler: Any
    """The task's goal sampler as the task file gives it (descriptive; the task.toml copy is used)."""


@dataclass(frozen=True)
class ActionPart(Record):
    """One part of the action: its map and columns; a relative part's `step`, an absolute part's
    `center` and `half_range`; the TCP target's box (`low`, `high`) where it has one."""

    map: str
    columns: tuple[int, int]
    step: float | None = None
    center: tuple[float, ...] | None = None
    half_range: tuple[float, ...] | None = None
    low: tuple[float, ...] | None = None
    high: tuple[float, ...] | None = None


@dataclass(frozen=True)
class HeldMap(Record):
    map: str
    value: tuple[float, ...]


@dataclass(frozen=True)
class SuctionColumn(Record):
    column: int
    on_above: float


@dataclass(frozen=True)
class Tool(Record):
    """The action's tool dimension: its column, actuator and rule (TaskInterface.tool)."""

    column: int
    actuator: str
    kind: Literal["suction", "gripper"]
    rule: str
    width_range_m: tuple[float, float] | None = None
    measured: str | None = None


@dataclass(frozen=True)
class ContractAction(Record):
    dim: int
    mode: str
    range: tuple[float, float]
    parts: tuple[ActionPart, ...]
    hold: tuple[HeldMap, ...]
    suction: SuctionColumn | None
    tool: Tool | None
    joint_step_rad: float | None


@dataclass(frozen=True)
class Workspace(Record):
    """The TCP target's box [m] in the world frame, and the action part that sets the target."""

    part: int
    low: tuple[float, ...]
    high: tuple[float, ...]
    frame: str
    unit: str


@dataclass(frozen=True)
class ContractIK(Record):
    map: str
    options: IKOptions


@dataclass(frozen=True)
class PolicyInput(Record):
    name: str
    dim: int
    dtype: str


@dataclass(frozen=True)
class PolicyOutput(Record):
    name: str
    dim: int
    dtype: str
    range: tuple[float, float]


@dataclass(frozen=True)
class Statistics(Record):
    mean: tuple[float, ...]
    var: tuple[float, ...]
    count: float


@dataclass(frozen=True)
class Normalizer(Record):
    applied: str
    rule: str
    epsilon: float
    clip: float
    statistics: Mapping[str, Statistics]


@dataclass(frozen=True)
class ContractPolicy(Record):
    file: str
    algo: str
    inputs: tuple[PolicyInput, ...]
    output: PolicyOutput
    normalizer: Normalizer | None


@dataclass(frozen=True)
class Contract(Record):
    """contract.json as a typed, frozen record (`read_contract`; the keys are the fields)."""

    format: str
    contract_version: int
    tsrl_version: str
    frames: str
    robot: ContractRobot
    task: ContractTask
    observation: ContractObservation
    goal: ContractGoal
    action: ContractAction
    workspace: Workspace | None
    ik: ContractIK | None
    policy: ContractPolicy
    run: Any
    """The run it was exported from (folder, checkpoint, env steps, config), or None (descriptive)."""
    files: Mapping[str, str]
    """sha256 of every other file of the export folder, by its path in the folder."""
    sha256: str


def load_contract(table: dict[str, Any], where: str) -> Contract:
    """The typed record of a contract's table (as JSON gives it); ContractError (one line naming
    `where` and the key) for a key that is unknown or missing or a value of the wrong type."""
    try:
        return load_table(Contract, table, source=where)
    except InvalidConfig as err:
        raise ContractError(f"{err} (export the run again)") from None


def sha256(path: Path) -> str:
    """Hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def contract_digest(contract: dict[str, Any]) -> str:
    """Hex sha256 of a contract's keys other than `sha256`, as canonical JSON (sorted keys, no spaces)."""
    body = {k: v for k, v in contract.items() if k != "sha256"}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


#: The largest normaliser mean or standard deviation an export accepts: far beyond any physical
#: observation of a task (m, rad, m/s), and far below what a damaged float byte gives (e.g. -4.9e307).
MAX_STATISTIC = 1e6


def check_normalizer_statistics(where: str, key: str, mean: Any, var: Any, count: Any) -> None:
    """Raises ContractError unless the statistics of one observation entry are usable: mean and var
    finite, var >= 0, |mean| and sqrt(var) <= MAX_STATISTIC, count > 0 (one line naming `where`)."""
    ranges = {"mean": (-MAX_STATISTIC, MAX_STATISTIC), "var": (0.0, MAX_STATISTIC**2)}
    for name, values in (("mean", mean), ("var", var)):
        lo, hi = ranges[name]
        bad = [v for v in _floats(values) if not (math.isfinite(v) and lo <= v <= hi)]
        if bad:
            bound = f"{lo:g} <= {name} <= {hi:g}"
            raise ContractError(
                f"{where}: normaliser {name} of {key!r} holds {bad[0]!r}; a usable normaliser has finite "
                f"statistics with {bound} (a damaged file? train or export again)"
            )
    if not (isinstance(count, int | float) and math.isfinite(count) and count > 0):
        raise ContractError(f"{where}: normaliser count of {key!r} is {count!r}; it must be > 0")


def _floats(values: Any) -> list[float]:
    """A number or a (nested) list of numbers as a flat list of floats (a non-number as NaN)."""
    if isinstance(values, list | tuple):
        return [v for x in values for v in _floats(x)]
    if hasattr(values, "tolist"):
        return _floats(values.tolist())
    return [float(values)] if isinstance(values, int | float) and not isinstance(values, bool) else [math.nan]


def check_values(contract: dict[str, Any], where: str) -> None:
    """Raises ContractError (one line naming `where`, the key, the value and what is accepted) unless
    the contract's limits are usable: joint limits finite with lower < upper, one per joint; speed and
    acceleration limits finite and > 0, one per joint; home inside the joint limits; control period and
    physics timestep > 0; the workspace finite with low < high; the normaliser's statistics usable."""
    robot, task = contract["robot"], contract["task"]
    n = len(robot["joints"])
    limits = robot["joint_limits"]
    if not (isinstance(limits, list) and len(limits) == n):
        raise ContractError(f"{where}: robot.joint_limits must hold {n} [lower, upper] pairs; got {limits!r}")
    for joint, pair in zip(robot["joints"], limits):
        values = _floats(pair)
        lo, hi = values if len(values) == 2 else (math.nan, math.nan)
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ContractError(
                f"{where}: robot.joint_limits of {joint!r} is {pair!r}; accepted: finite [lower, upper] with "
                "lower < upper (the safety layer needs finite limits on every joint)"
            )
    for key in ("max_joint_speed", "max_joint_acceleration"):
        values = _floats(robot[key])
        if len(values) != n or not all(math.isfinite(v) and v > 0 for v in values):
            raise ContractError(f"{where}: robot.{key} is {robot[key]!r}; accepted: {n} finite values > 0")
    home = _floats(robot["home_q"])
    inside = len(home) == n and all(lo <= q <= hi for q, (lo, hi) in zip(home, limits))
    if not inside:
        raise ContractError(
            f"{where}: robot.home_q is {robot['home_q']!r}; accepted: {n} values within joint_limits"
        )
    for key in ("control_period_s", "physics_timestep_s"):
        value = _floats(task[key])
        if not (len(value) == 1 and math.isfinite(value[0]) and value[0] > 0):
            raise ContractError(f"{where}: task.{key} is {task[key]!r}; accepted: a finite value > 0")
    workspace = contract.get("workspace")
    if workspace is not None:
        low, high = _floats(workspace["low"]), _floats(workspace["high"])
        ordered = len(low) == len(high) and all(
            math.isfinite(a) and math.isfinite(b) and a < b for a, b in zip(low, high)
        )
        if not ordered:
            raise ContractError(
                f"{where}: workspace is low {workspace['low']!r}, high {workspace['high']!r}; accepted: finite "
                "bounds of equal length with low < high"
            )
    normalizer = contract["policy"].get("normalizer")
    if normalizer is not None:
        for key in ("epsilon", "clip"):
            value = _floats(normalizer[key])
            if not (len(value) == 1 and math.isfinite(value[0]) and value[0] > 0):
                raise ContractError(f"{where}: policy.normalizer.{key} is {normalizer[key]!r}; accepted: > 0")
        for key, stats in normalizer["statistics"].items():
            check_normalizer_statistics(where, key, stats["mean"], stats["var"], stats["count"])


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


def read_contract(export_dir: Path | str) -> Contract:
    """The contract of an export folder (a typed, frozen record), after checking its version and
    every file's sha256.

    Raises:
        ContractError: no contract.json, not a tsrl contract, another major version of tsrl or
            another contract layout, a contract altered since export, unusable limits or normaliser
            statistics (check_values), a key or value the record does not take (load_contract), a
            file it lists missing or with another sha256 (one line naming the file and what was
            expected).
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
            f"{path}: contract_version {contract.get('contract_version')!r}; this tsrl reads {CONTRACT_VERSION} "
            "(export the run again)"
        )
    digest = contract_digest(contract)
    if contract.get("sha256") != digest:
        raise ContractError(
            f"{path}: altered since export (its sha256 is {contract.get('sha256')!r}, its content's {digest}); "
            "export the run again rather than editing the contract"
        )
    try:
        check_values(contract, str(path))
    except (KeyError, TypeError) as err:
        raise ContractError(f"{path}: a contract without {err} (export the run again)") from None
    files = contract.get("files")
    if not isinstance(files, dict) or POLICY not in files:
        raise ContractError(f"{path}: 'files' must map every file of the export to its sha256")
    record = load_contract(contract, str(path))
    for name, expected in record.files.items():
        file = folder / name
        if not file.is_file():
            raise ContractError(f"{file}: missing; the contract lists it with sha256 {expected}")
        actual = sha256(file)
        if actual != expected:
            raise ContractError(f"{file}: sha256 {actual} differs from the contract's {expected}")
    return record
