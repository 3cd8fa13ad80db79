"""Experiment definitions: a TOML file -> ExperimentConfig -> the grid of TrainConfigs it runs.

A definition is data, never code: tsrl.configs reads it into ExperimentConfig (and `[agent]` into
AgentConfig), every key checked, with an error that names the file, the bad key or value and the
accepted ones. docs/experiments.md describes the format.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from ..agents.config import AgentConfig, Algo, TrainConfig
from ..agents.transfer import EvalTask, Perturbation
from ..configs import load_table, read_toml
from ..exceptions import InvalidConfig, TsrlError, check_int, is_number

#: Folder of experiment definitions, relative to the repository root (the CLI's working directory).
EXPERIMENTS_DIR = "experiments"
SUFFIX = ".toml"
#: The validated ExperimentConfig, written into the experiment's results folder by each run of it.
EXPERIMENT_FILE = "experiment.json"
#: Folder of an experiment's recorded demonstrations ([demos]), inside its results folder.
DEMOS_DIR = "demos"
#: Environment of an experiment's worker processes (training and evaluation), set before they import
#: torch: one thread per BLAS/OpenMP pool (torch_threads = 1 in TrainConfig).
WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def local_workers(workers: int | None) -> int:
    """Local worker processes for `--workers`: as given, by default one per core available to us."""
    return workers or len(os.sched_getaffinity(0))


#: The grid axes of strings; a definition file may give one as a single string.
STRING_AXES: tuple[str, ...] = ("env", "obs", "action", "algo")

Key = tuple[str, str, str, str, str]
"""A configuration: (env, obs, action, algo, variant); its runs differ by seed. The variant names
other settings that differ between runs of a results folder (empty within one experiment)."""


#: Per-seed metrics a comparison can test (tsrl.experiments.aggregate computes them).
COMPARISON_METRICS: dict[str, str] = {
    "auc": "area under the success curve over env steps, normalised to [0, 1] (sample efficiency)",
    "final_success": "mean success rate of the last evaluations",
    "final_penalised": "mean share of evaluation episodes with a penalised step (e.g. touching an obstacle) in "
    "the last evaluations; tasks with penalties only",
    "success": "success rate of an evaluation-only arm ([[evaluate]]) over its episodes, at the end of training",
}
#: The one metric of evaluation-only arms; the others are of trained arms.
EVAL_METRIC = "success"
DIRECTIONS: tuple[str, ...] = ("greater", "less", "two-sided")


@dataclass(frozen=True)
class Comparison:
    """A pre-registered comparison of two arms of an experiment on one per-seed metric."""

    a: str
    """An arm: its label in the report, the grid values that differ between configurations joined by
    " / " (e.g. "fs1", or "fs1 / joint" when two axes vary)."""
    b: str
    """The arm `a` is compared with."""
    metric: str = "auc"
    """auc, final_success or final_penalised (COMPARISON_METRICS)."""
    direction: str = "greater"
    """The registered hypothesis: metric(a) greater than, less than, or different from (two-sided)
    metric(b); it sets the side of the test."""
    min_effect: float | None = None
    """The smallest difference of IQMs that matters (e.g. the one the paper claims), in the metric's
    units; the verdict says whether the study could detect it."""

    def __post_init__(self) -> None:
        for name in ("a", "b"):
            if not isinstance(getattr(self, name), str):
                raise InvalidConfig(f"{name} must be an arm's label (a string); got {getattr(self, name)!r}")
        if self.metric not in COMPARISON_METRICS:
            raise InvalidConfig(f"unknown metric {self.metric!r}; accepted: {', '.join(COMPARISON_METRICS)}")
        if self.direction not in DIRECTIONS:
            raise InvalidConfig(f"unknown direction {self.direction!r}; accepted: {', '.join(DIRECTIONS)}")
        if self.min_effect is not None and (not is_number(self.min_effect) or self.min_effect <= 0):
            raise InvalidConfig(f"min_effect must be a number > 0; got {self.min_effect!r}")


@dataclass(frozen=True)
class Evaluation:
    """An evaluation-only arm (the file's [[evaluate]] tables): each seed's final policy of a trained
    arm, evaluated after training on another task of the same layout (another arm: "train on A,
    evaluate on B"), or on its own, optionally over a swept perturbation (one arm per value).

    Each run's episodes are seeded apart from its training evaluations (fresh goals) and shared by
    every [[evaluate]] of the run, so arms on the same policy are paired. Results:
    `<experiment dir>/evaluations.csv`, summarised by `tsrl report`."""

    name: str
    """The arm's label in the report and in [[comparisons]] (with a sweep, `name@value` per value)."""
    arm: str
    """The trained arm whose policies are evaluated (its label, as [[comparisons]] name it)."""
    env: str
    """A registered id or a task file (relative to the experiment file) with the arm's layout."""
    episodes: int = 100
    """Deterministic episodes per seed."""
    perturb: Perturbation | None = None
    """A `[randomize]` key swept over values (`[evaluate.perturb]`: key, values), each its own arm,
    on the task as it is otherwise (tsrl.agents.transfer)."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or "@" in self.name:
            raise InvalidConfig(f"name must be a non-empty label without '@'; got {self.name!r}")
        check_int("episodes", self.episodes, 1)

    def labels(self) -> list[str]:
        """The labels of its arms: `name`, or `name@value` per swept value."""
        if self.perturb is None:
            return [self.name]
        return [f"{self.name}@{v:g}" for v in self.perturb.values]


@dataclass(frozen=True)
class FineTune:
    """Fine-tuning runs (the file's [[finetune]] tables): for every seed and (obs, action, algo) of the
    grid, a run on `env` that starts from the grid's run on `from_env` of the same seed, obs, action and
    algo (its final networks and normaliser: `tsrl train --init-from`), with the experiment's budget,
    evaluations and demonstrations. They start once their sources have finished. Their arms are labelled
    with the variant `init_from=True` (the grid's with `init_from=False`), as `tsrl report` names them."""

    from_env: str
    """One of the grid's env values: whose runs the fine-tuning runs start from."""
    env: str
    """The task they are trained on: a registered id or a task file (relative to the experiment file)
    of the same layout (typically the same task on the other arm)."""

    def __post_init__(self) -> None:
        for name in ("from_env", "env"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise InvalidConfig(f"{name} must be an env id or task file; got {getattr(self, name)!r}")


@dataclass(frozen=True)
class DemoRecipe:
    """Scripted demonstrations an experiment records once per (env, obs, action), before its runs, into
    `<experiment dir>/demos/<env>__<obs>__<action>.npz`; every run of that configuration trains with
    them (`[agent.demos]` sets batch share, BC weight and Q-filter)."""

    episodes: int
    """Successful episodes to record (the task's scripted solver, tsrl.envs.solvers.SOLVERS)."""
    seed: int = 0
    """Recording seed: the episodes' seeds are drawn from their own stream (demo_seeds)."""

    def __post_init__(self) -> None:
        check_int("episodes", self.episodes, 1)
        check_int("seed", self.seed, 0)


@dataclass(frozen=True)
class TaskBudget:
    """A budget of its own for one env of the grid (the file's [[budgets]] tables), where tasks of one
    experiment need different lengths of training: its runs get these instead of the experiment's."""

    env: str
    """One of the grid's env values."""
    total_timesteps: int
    """Budget of each run on `env` in env steps."""
    eval_freq: int | None = None
    """Evaluate every this many env steps; None: the experiment's eval_freq."""

    def __post_init__(self) -> None:
        if not isinstance(self.env, str) or not self.env:
            raise InvalidConfig(f"env must be an env id or task file; got {self.env!r}")
        check_int("total_timesteps", self.total_timesteps, 1)
        if self.eval_freq is not None:
            check_int("eval_freq", self.eval_freq, 1)


@dataclass(frozen=True)
class ExperimentConfig:
    """A grid of training runs: env x obs x action x algo x seeds, with one budget and one evaluation
    schedule, or one per env ([[budgets]]). Each list-valued field is an axis of the grid; `runs()`
    expands it."""

    name: str
    """Experiment name; results go to <out-dir>/<name>/. A file's name without .toml."""
    description: str = ""
    """One or two sentences: what the experiment compares, for the results' summary."""
    env: tuple[str, ...] = ("tsrl/UR5eReach-v0",)
    """Registered environment ids."""
    obs: tuple[str, ...] = ("",)
    """Observation presets (baseline, simple, fs0, fs1, fs2) or task-map spec strings; "" (the default):
    each task's own, as gym.make builds it."""
    action: tuple[str, ...] = ("",)
    """Action modes: taskspace, taskspace_orient, joint, task; "" (the default): each task's own."""
    algo: tuple[Algo | Literal[""], ...] = ("",)
    """Algorithms: ddpg, td3, sac, tqc (each combined with HER) or bc; "" (the default): the [agent]
    learner's (paper: ddpg, fast: td3)."""
    seeds: tuple[int, ...] = (0,)
    """Seeds of the runs (integers >= 0), e.g. [0, 1, 2, 3, 4]."""
    total_timesteps: int = 20_000
    """Budget of each run in env steps."""
    eval_freq: int = 500
    """Evaluate every this many env steps (and at step 0)."""
    eval_episodes: int = 20
    """Deterministic evaluation episodes per evaluation."""
    checkpoint_freq: int = 5000
    """Checkpoint every this many env steps (and at the end); an interrupted run resumes from the latest."""
    agent: AgentConfig = field(default_factory=AgentConfig)
    """Settings shared by every run (the file's [agent] table overrides AgentConfig's defaults); its
    `algo` is replaced by each grid point's."""
    agents: tuple[AgentConfig, ...] = ()
    """A grid axis of agents (the file's [[agents]] tables, each [agent] with its own changes), e.g. the
    paper's learner beside the fast one; none: `agent` alone. They must differ in what a run's name
    says (HER relabelling, demonstrations on or off, learner, action penalty): one folder holds the runs."""
    demos: DemoRecipe | None = None
    """Demonstrations every run trains with (the file's [demos] table), recorded by the experiment."""
    comparisons: tuple[Comparison, ...] = ()
    """Pre-registered comparisons (the file's [[comparisons]] tables), reported with effect, interval,
    Holm-adjusted p-value, power and verdict by `tsrl report`."""
    evaluate: tuple[Evaluation, ...] = ()
    """Evaluation-only arms (the file's [[evaluate]] tables), run after training."""
    finetune: tuple[FineTune, ...] = ()
    """Fine-tuning runs from another env's runs (the file's [[finetune]] tables), after the grid's."""
    budgets: tuple[TaskBudget, ...] = ()
    """Per-env budgets (the file's [[budgets]] tables): an env listed here has its own total_timesteps
    and eval_freq; the others have the experiment's."""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name or "/" in self.name or self.name.startswith("."):
            raise InvalidConfig(f"name must be a non-empty folder name; got {self.name!r}")
        if not isinstance(self.description, str):
            raise InvalidConfig(f"description must be a string; got {self.description!r}")
        for axis in (*STRING_AXES, "seeds"):
            values = getattr(self, axis)
            if not values:
                raise InvalidConfig(f"{axis} must be a non-empty list; got {list(values)!r}")
            repeated = sorted({v for v in values if values.count(v) > 1}, key=str)
            if repeated:
                raise InvalidConfig(f"{axis} lists {', '.join(map(repr, repeated))} more than once")
        if min(self.seeds) < 0:
            raise InvalidConfig(f"seeds must be integers >= 0; got {min(self.seeds)}")
        self._check_finetune()
        self._check_budgets()
        self._check_demos()
        self.runs()  # validates every grid point (obs, action, algo, seeds, budget) as a TrainConfig
        self._check_evaluations()
        self._check_comparisons()

    def arms(self) -> list[str]:
        """The labels of the trained configurations (the grid's, then the fine-tuning ones), as the
        report names them (config_labels over the runs' keys)."""
        keys = list(dict.fromkeys(self._run_keys()))
        return config_labels(keys)

    def arm_runs(self, arm: str, exp_dir: Path | None = None) -> list[TrainConfig]:
        """The runs (one per seed, in seed order) of the trained arm labelled `arm`."""
        keys = self._run_keys()
        distinct = list(dict.fromkeys(keys))
        label = dict(zip(distinct, config_labels(distinct), strict=True))
        runs = [cfg for cfg, key in zip(self.runs(exp_dir), keys, strict=True) if label[key] == arm]
        return sorted(runs, key=lambda cfg: cfg.seed)

    def _run_keys(self) -> list[Key]:
        """Each run's configuration key (env, obs, action, algo, variant), as the report makes them."""
        from .results import variants

        runs = self.runs()
        return [
            (cfg.env_id, cfg.obs, cfg.action, cfg.agent.algo, v)
            for cfg, v in zip(runs, variants(runs), strict=True)
        ]

    def eval_arms(self) -> list[str]:
        """The labels of the evaluation-only arms ([[evaluate]]), in file order."""
        return [label for e in self.evaluate for label in e.labels()]

    def _check_evaluations(self) -> None:
        arms, seen = self.arms(), set(self.arms())
        for i, e in enumerate(self.evaluate):
            if e.arm not in arms:
                raise InvalidConfig(f"[evaluate[{i}]] unknown arm {e.arm!r}; accepted: {', '.join(arms)}")
            for label in e.labels():
                if label in seen:
                    raise InvalidConfig(f"[evaluate[{i}]] the label {label!r} is taken; give another name")
                seen.add(label)

    def _check_comparisons(self) -> None:
        arms, evals = self.arms(), self.eval_arms()
        for i, c in enumerate(self.comparisons):
            accepted = evals if c.metric == EVAL_METRIC else arms
            kind = (
                f"evaluation-only arm (metric {EVAL_METRIC}: [[evaluate]] labels)"
                if accepted is evals
                else "arm"
            )
            for arm in (c.a, c.b):
                if arm not in accepted:
                    raise InvalidConfig(
                        f"[comparisons[{i}]] unknown {kind} {arm!r}; accepted: {', '.join(accepted) or 'none'}"
                    )
            if c.a == c.b:
                raise InvalidConfig(f"[comparisons[{i}]] compares arm {c.a!r} with itself")

    def _check_finetune(self) -> None:
        for i, f in enumerate(self.finetune):
            if f.from_env not in self.env:
                raise InvalidConfig(
                    f"[finetune[{i}]] from_env {f.from_env!r} is not in the grid; accepted: {', '.join(self.env)}"
                )

    def _check_budgets(self) -> None:
        seen: set[str] = set()
        for i, b in enumerate(self.budgets):
            if b.env not in self.env:
                raise InvalidConfig(
                    f"[budgets[{i}]] env {b.env!r} is not in the grid; accepted: {', '.join(self.env)}"
                )
            if b.env in seen:
                raise InvalidConfig(f"[budgets[{i}]] env {b.env!r} has a budget already")
            seen.add(b.env)
        if self.budgets and self.finetune:  # a fine-tuning run starts once its source is at its budget
            raise InvalidConfig("[[budgets]] with [[finetune]]: accepted: one budget for every env")

    def _check_demos(self) -> None:
        if self.demos is None:
            return
        if any(a.demos.path is not None for a in self.grid_agents()):
            raise InvalidConfig("[demos] records the demonstrations: leave [agent.demos] path unset")
        from ..agents.config import TASK_ACTION, task_defaults
        from ..envs.solvers import solver_for

        envs = list(dict.fromkeys([*self.env, *(f.env for f in self.finetune)]))
        for env, given in itertools.product(envs, self.action):
            action = given or task_defaults(env)[1]  # "": the task's own
            try:
                solver_for(env, None if action == TASK_ACTION else action)
            except InvalidConfig as err:
                raise InvalidConfig(f"[demos]: {err}") from None

    def runs(self, exp_dir: Path | None = None) -> list[TrainConfig]:
        """One TrainConfig per grid point, seed-major (every configuration's seed 0 first), so that a
        partial experiment already compares all configurations; then the [[finetune]] runs in the same
        order, each with `init_from` its source run's folder. With [demos], each run's demonstration
        file is `demo_file(exp_dir, cfg)`. exp_dir defaults to ./<name>."""
        folder = exp_dir if exp_dir is not None else Path(self.name)
        agents = self.grid_agents()
        grid = [
            self._run(env, obs, action, algo, seed, folder, agent)
            for seed, env, obs, action, algo, agent in itertools.product(
                self.seeds, self.env, self.obs, self.action, self.algo, agents
            )
        ]
        tuned = [
            dataclasses.replace(
                self._run(f.env, obs, action, algo, seed, folder, agent),
                init_from=str(
                    folder / self._run(f.from_env, obs, action, algo, seed, folder, agent).run_name
                ),
            )
            for seed, f, obs, action, algo, agent in itertools.product(
                self.seeds, self.finetune, self.obs, self.action, self.algo, agents
            )
        ]
        return grid + tuned

    def grid_agents(self) -> tuple[AgentConfig, ...]:
        """The agents of the grid: the [[agents]], or the [agent] alone."""
        return self.agents or (self.agent,)

    def _run(
        self,
        env: str,
        obs: str,
        action: str,
        algo: Algo | Literal[""],
        seed: int,
        folder: Path,
        agent: AgentConfig,
    ) -> TrainConfig:
        budget = next((b for b in self.budgets if b.env == env), None)
        cfg = TrainConfig(
            env_id=env,
            obs=obs,
            action=action,
            seed=seed,
            total_timesteps=self.total_timesteps if budget is None else budget.total_timesteps,
            eval_freq=self.eval_freq if budget is None or budget.eval_freq is None else budget.eval_freq,
            eval_episodes=self.eval_episodes,
            checkpoint_freq=self.checkpoint_freq,
            agent=dataclasses.replace(agent, algo=algo or agent.algo),
        )
        if self.demos is None:
            return cfg
        path = str(demo_file(folder, cfg))
        demos = dataclasses.replace(cfg.agent.demos, path=path)
        return dataclasses.replace(cfg, agent=dataclasses.replace(cfg.agent, demos=demos))

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def demo_file(exp_dir: Path, cfg: TrainConfig) -> Path:
    """Where an experiment keeps the recorded demonstrations of `cfg`'s env, obs and action."""
    return exp_dir / DEMOS_DIR / f"{cfg.env_name}.npz"


def load_experiment(path: Path | str, check_envs: bool = True) -> ExperimentConfig:
    """Reads and validates a definition file; `check_envs` also builds each (env, obs, action) once,
    so an unknown observation spec fails here rather than inside a worker.

    Raises InvalidConfig naming the file, the bad key or value, and the accepted ones.
    """
    path = Path(path)
    data = read_toml(path)
    for axis in STRING_AXES:  # a single string is a one-value axis
        if isinstance(data.get(axis), str):
            data[axis] = [data[axis]]
    envs = data.get("env")
    if isinstance(envs, list):  # task files are relative to the experiment file
        data["env"] = [
            str(path.parent / e)
            if isinstance(e, str) and e.endswith(".toml") and not Path(e).is_absolute()
            else e
            for e in envs
        ]
    for kind, key in (("evaluate", "env"), ("finetune", "env"), ("finetune", "from_env"), ("budgets", "env")):
        for table in _tables(data, kind):
            env = table.get(key) if isinstance(table, dict) else None
            if isinstance(env, str) and env.endswith(".toml") and not Path(env).is_absolute():
                table[key] = str(path.parent / env)
    agent = data.get("agent")
    for where, table in [
        ("[agent]", agent),
        *((f"[agents[{i}]]", a) for i, a in enumerate(_tables(data, "agents"))),
    ]:
        if isinstance(table, dict) and "algo" in table:
            raise InvalidConfig(f"{path}: {where} algo is a grid axis: set `algo = [...]` at the top level")
    if _tables(data, "agents"):  # each [[agents]] is [agent] with its changes
        base = agent if isinstance(agent, dict) else {}
        data["agents"] = [_merged(base, a) if isinstance(a, dict) else a for a in data["agents"]]
    exp = load_table(ExperimentConfig, data, source=path, extra={"name": path.name.removesuffix(SUFFIX)})
    check_run_names(exp, where=str(path))
    if check_envs:
        check_environments(exp, where=str(path))
    return exp


def _tables(data: dict[str, Any], key: str) -> list[Any]:
    """The tables of an array of tables `key` ([] where there is none or it is not a list)."""
    value = data.get(key)
    return value if isinstance(value, list) else []


def _merged(base: dict[str, Any], changes: dict[str, Any]) -> dict[str, Any]:
    """`base` with `changes` over it, sub-tables merged key by key."""
    out = dict(base)
    for key, value in changes.items():
        both = isinstance(value, dict) and isinstance(out.get(key), dict)
        out[key] = _merged(out[key], value) if both else value
    return out


def check_run_names(exp: ExperimentConfig, where: str = "experiment") -> None:
    """Raises InvalidConfig (one line) where two runs of `exp` would share a run folder (task files of
    one file name in two folders): the second would fail only after the first had trained."""
    seen: dict[str, TrainConfig] = {}
    for cfg in exp.runs():
        first = seen.setdefault(cfg.run_name, cfg)
        if first is not cfg and first.env_id == cfg.env_id:
            raise InvalidConfig(
                f"{where}: two [[agents]] give one run folder name {cfg.run_name!r}; accepted: agents that "
                "differ in what a run's name says (her relabel, demonstrations on or off, learner, action_l2, residual, return_bound)"
            )
        if first is not cfg:
            raise InvalidConfig(
                f"{where}: env {first.env_id!r} and env {cfg.env_id!r} give one run folder name "
                f"{cfg.run_name!r}; accepted: task files of distinct file names (rename one)"
            )


def check_environments(exp: ExperimentConfig, where: str = "experiment") -> None:
    """Builds each distinct (env, obs, action) of `exp` once; raises InvalidConfig naming the bad one."""
    import gymnasium as gym

    from ..agents.config import check_env_id

    seen: set[tuple[str, str, str]] = set()
    for cfg in exp.runs():
        key = (cfg.env_id, cfg.obs, cfg.action)
        if key in seen:
            continue
        seen.add(key)
        try:
            if cfg.is_tsrl_env:
                check_env_id(cfg.env_id)
            gym.make(cfg.gym_id, **cfg.env_kwargs).close()
        except TsrlError as err:
            raise InvalidConfig(
                f"{where}: env {cfg.env_id!r} with obs {cfg.obs!r}, action {cfg.action!r}: {err}"
            ) from None
        except gym.error.Error as err:
            raise InvalidConfig(f"{where}: env {cfg.env_id!r}: {err}") from None
    for i, e in enumerate(exp.evaluate):
        try:
            evaluation_tasks(exp, e)
        except TsrlError as err:
            raise InvalidConfig(f"{where}: [evaluate[{i}]] {err}") from None


def evaluation_tasks(exp: ExperimentConfig, evaluation: Evaluation) -> list[EvalTask]:
    """The tasks of an [[evaluate]] table (one per swept value), each checked against the layout of
    its trained arm (tsrl.agents.transfer; InvalidConfig, one line, when it differs)."""
    from ..agents.transfer import check_layout, eval_task, sweep

    cfg = exp.arm_runs(evaluation.arm)[0]
    target = eval_task(cfg, evaluation.env)
    tasks = [target] if evaluation.perturb is None else sweep(target, evaluation.perturb)
    for t in tasks:
        check_layout(cfg, t)
    return tasks


def known_experiments(folders: list[Path]) -> list[str]:
    """Names of the definition files in `folders`."""
    return sorted({p.name.removesuffix(SUFFIX) for d in folders if d.is_dir() for p in d.glob(f"*{SUFFIX}")})


def search_folders() -> list[Path]:
    """Where experiment names are looked up: ./experiments, then the source checkout's experiments/
    when tsrl is installed from one in editable mode (so the CLI works from any folder)."""
    folders = [Path(EXPERIMENTS_DIR)]
    checkout = Path(__file__).resolve().parents[3] / EXPERIMENTS_DIR
    if (
        (checkout.parent / "pyproject.toml").is_file()
        and checkout.is_dir()
        and checkout != folders[0].resolve()
    ):
        folders.append(checkout)
    return folders


def resolve_experiment(name_or_file: str) -> Path:
    """The definition file of an experiment name (experiments/<name>.toml) or path (ends in .toml)."""
    as_path = Path(name_or_file)
    if name_or_file.endswith(SUFFIX) or len(as_path.parts) > 1:
        if not as_path.is_file():
            raise InvalidConfig(f"experiment file {as_path} does not exist")
        return as_path
    folders = search_folders()
    for folder in folders:
        candidate = folder / f"{name_or_file}{SUFFIX}"
        if candidate.is_file():
            return candidate
    known = known_experiments(folders)
    raise InvalidConfig(
        f"unknown experiment {name_or_file!r}; known: {', '.join(known) or 'none'} "
        f"(in {', '.join(map(str, folders))}), or pass the path of a .toml file"
    )


def config_labels(keys: list[Key]) -> list[str]:
    """Short labels naming only what differs between configurations (obs alone if nothing does); a task
    file in the env axis is named by its file name without the folder and suffix. An obs or action
    that each env has one of (each task's own, "") goes with the env and is left out."""
    varying = [i for i in range(len(keys[0])) if len({k[i] for k in keys}) > 1]
    env_own = [
        i for i in (1, 2) if 0 in varying and len({(k[0], k[i]) for k in keys}) == len({k[0] for k in keys})
    ]
    shown = [i for i in varying if i not in env_own] or [1]
    return [" / ".join(env_label(k[i]) for i in shown) for k in keys]


def env_label(env: str) -> str:
    """An env axis value as reports name it: a task file by its file name without folder and suffix
    (results stay free of machine-specific paths), anything else as it is."""
    return Path(env).stem if env.endswith(".toml") else env
