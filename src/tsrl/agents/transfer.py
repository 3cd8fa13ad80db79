"""Where a run's policy is evaluated: another task of the same layout (another arm, model or scene),
perturbed by one `[randomize]` key (a robustness profile). Imports no torch, so the CLI checks its
input before stable-baselines3 loads.

The evaluated task is the task as it is (its own `[randomize]` included), with the swept key set:
a scale key's value v is the range [v, v] (servo_gain = 2: every servo's gains doubled), so is
joint_damping's (v N m s/rad added) and action_latency's (exactly v control periods, where the
task's own key draws 0..k); another magnitude key's value is the magnitude (docs/tasks.md).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..envs.registration import TASK_ENV_ID
from ..envs.tasks import RANDOMIZE_MAGNITUDES, RANDOMIZE_SCALES, Task, load_task
from ..exceptions import InvalidConfig, is_number
from .config import TASK_FILE_SUFFIX, TrainConfig, check_env_id

if TYPE_CHECKING:
    from ..envs.base import TaskEnv

#: The `[randomize]` keys a sweep may set: scales (a value v means [v, v]), the added damping (also
#: [v, v]) and the magnitudes.
PERTURB_KEYS: tuple[str, ...] = (*RANDOMIZE_SCALES, "joint_damping", *RANDOMIZE_MAGNITUDES)
_RANGE_KEYS = (*RANDOMIZE_SCALES, "joint_damping")


@dataclass(frozen=True)
class Perturbation:
    """One `[randomize]` key swept over values (`--perturb KEY=V1,V2,...`, or an experiment's
    `[evaluate.perturb]` table)."""

    key: str
    """A `[randomize]` key (PERTURB_KEYS)."""
    values: tuple[float, ...]
    """Its values, each evaluated on its own: a scale's v means [v, v]; a magnitude as it is."""

    def __post_init__(self) -> None:
        if self.key not in PERTURB_KEYS:
            raise InvalidConfig(f"unknown perturbation key {self.key!r}; accepted: {', '.join(PERTURB_KEYS)}")
        if not self.values:
            raise InvalidConfig(f"perturbation {self.key} needs at least one value")
        for v in self.values:
            if not is_number(v) or not math.isfinite(v):
                raise InvalidConfig(f"perturbation {self.key} = {v!r}; accepted: finite numbers")
            if v < 0 or (v == 0 and self.key in RANDOMIZE_SCALES):  # a scale of 0 removes the thing
                least = "> 0" if self.key in RANDOMIZE_SCALES else ">= 0"
                raise InvalidConfig(f"perturbation {self.key} = {v:g}; accepted: values {least}")
            if self.key == "action_latency" and v != int(v):
                raise InvalidConfig(f"perturbation action_latency = {v:g}; accepted: whole control periods")
        if len(set(self.values)) < len(self.values):
            raise InvalidConfig(f"perturbation {self.key} lists a value more than once: {self.text}")

    @property
    def text(self) -> str:
        """`KEY=V1,V2,...`, as --perturb takes it."""
        return f"{self.key}=" + ",".join(f"{v:g}" for v in self.values)


def parse_perturb(text: str) -> Perturbation:
    """`KEY=V1,V2,...` -> Perturbation; a bad key or value is one line naming it and the accepted."""
    key, sep, values = text.partition("=")
    if not sep or not values.strip():
        raise InvalidConfig(
            f"--perturb {text!r}: expected KEY=V1,V2,... with KEY one of {', '.join(PERTURB_KEYS)}"
        )
    parsed: list[float] = []
    for v in values.split(","):
        try:
            parsed.append(float(v))
        except ValueError:
            raise InvalidConfig(f"--perturb {key.strip()}: {v.strip()!r} is not a number") from None
    try:
        return Perturbation(key.strip(), tuple(parsed))
    except InvalidConfig as err:
        raise InvalidConfig(f"--perturb: {err}") from None


def target_env(env_id: str | None = None, task: str | Path | None = None) -> str | None:
    """The one evaluated environment of `env_id` (a registered id) or `task` (a task file), None for
    the run's own; both given is an error."""
    if env_id is not None and task is not None:
        raise InvalidConfig("give --env or --task, not both")
    if task is not None and not str(task).endswith(".toml"):
        raise InvalidConfig(f"--task {task}: expected a task file (*.toml); registered ids go to --env")
    return str(task) if task is not None else env_id


def base_task(env_id: str) -> Task:
    """The Task of a registered tsrl id or a task file (unknown ids: one line listing the accepted)."""
    import gymnasium as gym

    if env_id.endswith(TASK_FILE_SUFFIX):
        from .task_record import recorded_task

        path = Path(env_id).expanduser().resolve()
        recorded = recorded_task(path)  # a run's copy of its task: as the run recorded it
        return load_task(path) if recorded is None else recorded
    check_env_id(env_id)
    return load_task(gym.spec(env_id).kwargs["task"])


def perturbed(task: Task, key: str, value: float) -> Task:
    """`task` with `[randomize]` key set to `value` (see the module docstring); a value out of the
    key's range (negative, latency of the whole episode, ...) is one line naming it."""
    setting: Any = (
        (value, value)
        if key in _RANGE_KEYS
        else (int(value), int(value))  # exactly this many control periods
        if key == "action_latency"
        else value
    )
    try:
        return dataclasses.replace(task, randomize=dataclasses.replace(task.randomize, **{key: setting}))
    except InvalidConfig as err:
        raise InvalidConfig(f"perturbation {key}={value:g} on {task.name}: {err}") from None


@dataclass(frozen=True)
class EvalTask:
    """A task a run's policy is evaluated on, under the run's observation and action."""

    name: str
    """What it is called in tables: the env id or task file's name, with the perturbation if any."""
    task: Task

    def env_kwargs(self, cfg: TrainConfig) -> dict[str, Any]:
        """gym.make's keyword arguments for tsrl/Task-v0: the task, its episode length, the run's
        obs and action."""
        return cfg.env_kwargs | {"task": self.task, "max_episode_steps": self.task.episode_steps}


def eval_task(cfg: TrainConfig, env_id: str | None = None) -> EvalTask:
    """The task `env_id` (a registered id or task file; default: the run's own), unperturbed."""
    if not cfg.is_tsrl_env:
        raise InvalidConfig(
            f"{cfg.env_id} is not a tsrl environment; only runs on tsrl tasks are evaluated on other tasks"
        )
    target = cfg.env_id if env_id is None else env_id
    name = Path(target).stem if target.endswith(TASK_FILE_SUFFIX) else target
    return EvalTask(name, base_task(target))


def sweep(target: EvalTask, perturbation: Perturbation) -> list[EvalTask]:
    """One EvalTask per value of `perturbation` (every value checked first)."""
    return [
        EvalTask(f"{target.name} [{perturbation.key}={v:g}]", perturbed(target.task, perturbation.key, v))
        for v in perturbation.values
    ]


def check_layout(cfg: TrainConfig, target: EvalTask) -> None:
    """Raises InvalidConfig, one line naming the first differing row or part, unless `target` (under the
    run's observation and action) has the layout the run's policy was trained on (tsrl.envs.layout)."""
    _check(cfg.gym_id, cfg.env_kwargs, _name(cfg.env_id), TASK_ENV_ID, target.env_kwargs(cfg), target.name)


def check_run_layouts(trained: TrainConfig, other: TrainConfig) -> None:
    """Raises InvalidConfig, as check_layout, unless the envs of two runs (each with its own observation
    and action) share one layout; each is named with its observation and action, which tell two runs
    on the same task apart."""
    _check(
        trained.gym_id,
        trained.env_kwargs,
        _run_name(trained),
        other.gym_id,
        other.env_kwargs,
        _run_name(other),
    )


def _run_name(cfg: TrainConfig) -> str:
    return f"{_name(cfg.env_id)} (observation {cfg.obs}, action {cfg.action})"


def _check(
    gym_a: str, kwargs_a: dict[str, Any], name_a: str, gym_b: str, kwargs_b: dict[str, Any], name_b: str
) -> None:
    import gymnasium as gym

    from ..envs.layout import check_same_layout, layout

    env_a = gym.make(gym_a, **kwargs_a)
    try:
        env_b = gym.make(gym_b, **kwargs_b)
        try:
            check_same_layout(layout(_task_env(env_a)), layout(_task_env(env_b)), name_a, name_b)
        finally:
            env_b.close()
    finally:
        env_a.close()


def _task_env(env: Any) -> TaskEnv:
    """The TaskEnv inside gym.make's wrappers (tsrl ids and tsrl/Task-v0 build one)."""
    from ..envs.base import TaskEnv

    inner = env.unwrapped
    assert isinstance(inner, TaskEnv), type(inner)
    return inner


def _name(env_id: str) -> str:
    return Path(env_id).stem if env_id.endswith(TASK_FILE_SUFFIX) else env_id
