"""The `tsrl` command line: train, evaluate, render, plot, show, demos, experiment, report, ...

Built with tyro: a command is a frozen dataclass whose fields are its options (each field's attribute
docstring its help text, its type and default those of the option) and whose run() does the work;
COMMANDS maps command names to these classes. `tsrl train`'s options are the fields of
tsrl.agents.TrainConfig and its nested AgentConfig, HerConfig and DemoConfig, so a new config field is
a new option. A command with one verb (`tsrl demos record`) takes it as a positional Literal field. Bad input ends with one line on stderr naming what is
accepted, exit code 2.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Protocol

import tyro
import tyro._errors
from tyro.conf import Positional, arg

from .agents.config import TrainConfig, check_env_id
from .agents.run_folder import CONFIG_FILE, check_not_locked, load_config, run_config
from .assets import SCENES
from .deploy.cli import DEPLOY_COMMANDS
from .exceptions import InvalidConfig, TsrlError
from .experiments.cli import EXPERIMENT_COMMANDS
from .robot_check import ROBOT_COMMANDS
from .show import render_poses

RunDir = Annotated[Path, arg(metavar="RUN_DIR")]


class Command(Protocol):
    """A `tsrl` command: its options are its dataclass fields; run() returns the exit code."""

    def run(self) -> int: ...


@dataclass(frozen=True)
class Train:
    """Train DDPG/TD3/SAC + HER into a self-describing, resumable run folder."""

    config: Annotated[TrainConfig, arg(name="")]
    """The run (no default instance: obs and action not given stay empty, so that TrainConfig gives a
    task file its own)."""
    out_dir: Path = Path("results")
    """Parent of the run folder <out-dir>/<env>__<obs>__<action>__<algo>__s<seed>, which gets
    config.json, task/ (copies of the task's files), progress.csv, tb/ (TensorBoard), checkpoints/ and
    learning_curve.png."""
    resume: Annotated[Path | None, arg(metavar="RUN_DIR")] = None
    """Continue this run from its newest usable checkpoint (a damaged one is skipped with a warning); only
    --total-timesteps may be given with it."""
    progress: bool = True
    """Show a progress bar."""

    def run(self) -> int:
        # Validation first; torch and stable-baselines3 load only once the input is known to be good.
        if self.resume is None:
            check_env_id(self.config.env_id)
            _check_env_options(self.config)
            from .agents.init_from import check_init_from

            check_init_from(self.config)
        else:
            check_not_locked(self.resume)
        from .agents.training import TrainingInterrupted, resume, train

        try:
            if self.resume is None:
                train(self.config, self.out_dir, progress_bar=self.progress)
            else:  # self.config is the run's own, with_run_config made sure
                resume(self.resume, self.config.total_timesteps, progress_bar=self.progress)
        except TrainingInterrupted as stop:
            print(f"tsrl train: {stop}", file=sys.stderr)
            return 128 + stop.signum
        except KeyboardInterrupt:  # a second Ctrl-C (the first stops at the next safe point)
            run_dir = self.resume or self.out_dir / self.config.run_name
            if not (run_dir / CONFIG_FILE).is_file():
                raise  # before the run folder was made: main's line
            print(
                "tsrl train: interrupted at once, without saving a checkpoint; "
                f"continue with: tsrl train --resume {run_dir}",
                file=sys.stderr,
            )
            return 128 + signal.SIGINT
        return 0

    def with_learner(self, argv: Sequence[str]) -> Train:
        """`tsrl train --learner fast ...`: the options parsed again over that preset's defaults, so the
        options not given take the preset's values and the given ones win (AgentConfig.learner)."""
        from .agents.config import AgentConfig

        # the env given: obs and action not given are its own (a task file's; TrainConfig.obs)
        preset = TrainConfig(env_id=self.config.env_id, agent=AgentConfig(learner=self.config.agent.learner))
        with _one_line_errors():
            return tyro.cli(
                Train, args=argv, prog="tsrl train", default=dataclasses.replace(self, config=preset)
            )

    def with_run_config(self, argv: Sequence[str]) -> Train:
        """`tsrl train --resume RUN_DIR ...`: the options parsed again over the run's own config.

        An option whose value differs from the run's, besides --total-timesteps, is an error.
        """
        assert self.resume is not None
        run_cfg = run_config(self.resume, notify=False)  # on its recorded task (agents.task_record)
        with _one_line_errors():
            again = tyro.cli(
                Train, args=argv, prog="tsrl train", default=dataclasses.replace(self, config=run_cfg)
            )
        flags = _train_flags()
        given = [
            _given(flags[path], argv)
            for path in _differences(again.config, run_cfg)
            if path != "total_timesteps"
        ]
        if given:
            raise InvalidConfig(
                f"--resume continues a run with its own config.json; only --total-timesteps may be "
                f"given with it, got {', '.join(given)}"
            )
        return again


@dataclass(frozen=True)
class Evaluate:
    """Success rate and final distance of a run's newest usable policy, on its own task or another of
    the same layout (another arm), or over a swept perturbation (a robustness profile)."""

    run_dir: Positional[RunDir]
    """A run folder written by `tsrl train`; with --perturb also an experiment's results folder (each of
    its runs; IQM and interval across seeds per configuration)."""
    episodes: int = 50
    """Deterministic episodes, each with its own seed."""
    seed: int | None = None
    """Seed of the episode seeds (default: the run's)."""
    env: str | None = None
    """Evaluate on this registered environment instead of the run's own (same layout: observation rows,
    goal rows, action parts and control period; checked first)."""
    task: Annotated[Path | None, arg(metavar="FILE")] = None
    """Evaluate on this task file instead (same layout)."""
    perturb: Annotated[str | None, arg(metavar="KEY=V1,V2,...")] = None
    """Sweep one [randomize] key (docs/tasks.md) over the evaluated task: a scale's value v is [v, v]
    (servo_gain=0.5,1,2), a magnitude as given (observation_noise=0,0.005,0.01); writes a CSV table
    and a plot (success against the value) and prints the table."""
    out: Annotated[Path | None, arg(metavar="FILE.csv")] = None
    """The table of --perturb (its plot beside it, .png); default RUN_DIR/perturb__KEY[__ENV].csv."""
    record: Annotated[Path | None, arg(metavar="DIR")] = None
    """Also write --episodes rollouts of the policy (successful or not, at demonstration seeds of --seed)
    as a LeRobotDataset v3 folder, as `tsrl demos record --format lerobot` does (docs/datasets.md)."""
    camera: Annotated[str | None, arg(metavar="NAME")] = None
    """With --record: also this camera's frames as video, as `tsrl demos record --camera` writes them."""

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise InvalidConfig(f"--episodes must be >= 1; got {self.episodes}")
        if self.camera is not None and self.record is None:
            raise InvalidConfig(
                f"--camera {self.camera}: video of the rollouts of --record; give --record DIR"
            )
        if self.record is not None and (self.env, self.task, self.perturb) != (None, None, None):
            raise InvalidConfig(
                "--record writes rollouts on the run's own task; not with --env, --task or --perturb"
            )
        if self.record is not None:
            from .agents.demo_lerobot import import_pyarrow

            import_pyarrow()  # missing: one line before the evaluation runs
        if self.out is not None and self.perturb is None:
            raise InvalidConfig("--out names the table of --perturb; give --perturb KEY=V1,V2,...")
        if self.out is not None and not (self.out.parent.is_dir() and os.access(self.out.parent, os.W_OK)):
            raise InvalidConfig(
                f"--out {self.out}: no writable folder {self.out.parent}; accepted: a .csv file in an "
                "existing folder (checked before the evaluation runs)"
            )

    def run(self) -> int:
        from .agents.transfer import check_layout, eval_task, parse_perturb, sweep, target_env

        # Bad input is one line before torch loads: the run, the target's layout, each swept value.
        perturbation = parse_perturb(self.perturb) if self.perturb is not None else None
        target = target_env(self.env, self.task)
        if perturbation is None or (self.run_dir / CONFIG_FILE).is_file():
            cfg = run_config(self.run_dir, notify=False)  # on its recorded task (agents.task_record)
            base = eval_task(cfg, target)
            for t in [base] if perturbation is None else sweep(base, perturbation):
                check_layout(cfg, t)
        if perturbation is not None:
            from .experiments.evaluations import write_profile

            for line in write_profile(self.run_dir, perturbation, self.episodes, self.seed, target, self.out):
                print(line)
            return 0
        if self.camera is not None:
            from .agents.lerobot_video import check_camera

            check_camera(load_config(self.run_dir), self.camera)  # unknown: one line before the evaluation
        from .agents.evaluation import evaluate_run

        out = evaluate_run(self.run_dir, self.episodes, self.seed, env_id=target)
        r = out.result
        print(
            f"{self.run_dir} ({out.env_steps} env steps) on {out.task}: success rate {r.success_rate:.2f} "
            f"({round(r.success_rate * r.episodes)}/{r.episodes} episodes), "
            f"mean final distance {r.mean_final_distance:.4f} m"
        )
        if self.record is not None:  # the policy's rollouts, successful or not, on the run's own task
            from .agents.demo_files import summary_line
            from .agents.demo_lerobot import save_lerobot
            from .agents.demonstrators import record_demos

            run = load_config(self.run_dir)
            seed = run.seed if self.seed is None else self.seed
            rollouts = record_demos(
                run.env_id, self.episodes, policy=self.run_dir, seed=seed, keep_failed=True
            )
            print(summary_line(rollouts, save_lerobot(rollouts, self.record, run, self.camera)))
        return 0


@dataclass(frozen=True)
class Render:
    """Video of a run's newest usable policy, rendered off-screen."""

    run_dir: Positional[RunDir]
    """A run folder written by `tsrl train`."""
    out: Path = Path("video.mp4")
    """mp4 (or .gif) file."""
    episodes: int = 2
    """Episodes in the video."""
    seed: int | None = None
    """Seed of the episode seeds (default: the run's)."""
    size: Annotated[tuple[int, int], arg(metavar="W H")] = (480, 480)
    """Frame width and height in pixels."""
    camera: Annotated[str | None, arg(metavar="NAME")] = None
    """A camera of the task's model (MJCF <camera name=...>); default: a camera aimed at the task's
    workspace (the goal box and the TCP at home)."""

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise InvalidConfig(f"--episodes must be >= 1; got {self.episodes}")
        if min(self.size) < 16:
            raise InvalidConfig(f"--size must be at least 16 16; got {self.size[0]} {self.size[1]}")

    def run(self) -> int:
        load_config(self.run_dir)  # a clear error before torch loads
        from .agents.evaluation import render_run

        print(f"wrote {render_run(self.run_dir, self.out, self.episodes, self.seed, self.size, self.camera)}")
        return 0


@dataclass(frozen=True)
class Plot:
    """Learning curves (eval success vs env steps; IQM across seeds, as tsrl report) of run folders."""

    run_dirs: Positional[Annotated[tuple[Path, ...], arg(metavar="RUN_DIR")]]
    """Run folders written by `tsrl train`."""
    out: Path = Path("learning_curve.png")
    """PNG file."""

    def __post_init__(self) -> None:
        if not self.run_dirs:
            raise InvalidConfig("tsrl plot needs at least one RUN_DIR")

    def run(self) -> int:
        from .experiments.aggregate import plot_runs

        for run_dir in self.run_dirs:
            load_config(run_dir)  # a clear error for a folder that is not a run
        print(f"wrote {plot_runs(list(self.run_dirs), self.out)}")
        return 0


@dataclass(frozen=True)
class Show:
    """Render a scene (built in or an MJCF file) at home and a few random poses to PNG files."""

    out_dir: Path = Path("results/show")
    """Folder for the PNG files."""
    scene: Annotated[str, arg(help=f"Built-in scene ({', '.join(SCENES)}) or an MJCF file.")] = "reach"
    poses: int = 3
    """Number of random poses besides home."""
    seed: int = 0
    """Seed of the random poses."""
    camera: Annotated[str | None, arg(metavar="NAME")] = None
    """A camera of the scene's model (MJCF <camera name=...>); default: a camera framing the bodies its
    joints move and its mocap bodies at home."""

    def __post_init__(self) -> None:
        if self.poses < 0:
            raise InvalidConfig(f"--poses must be >= 0; got {self.poses}")

    def run(self) -> int:
        for path in render_poses(self.out_dir, self.scene, self.poses, self.seed, self.camera):
            print(f"wrote {path}")
        return 0


@dataclass(frozen=True)
class Demo(Show):
    """Deprecated name of `tsrl show`, which it runs; it goes in the next release."""

    def run(self) -> int:
        print(
            "tsrl: 'tsrl demo' is deprecated and goes in the next release; use 'tsrl show'", file=sys.stderr
        )
        return super().run()


@dataclass(frozen=True)
class Demos:
    """Record demonstration episodes for `tsrl train --demos FILE` (tsrl.agents.demonstrators)."""

    command: Positional[Literal["record"]]
    """record: a demonstrator's successful episodes into a .npz file (the built-in task's scripted
    solver, tsrl.envs.solvers.SOLVERS, or a trained run's policy with --policy)."""
    out: Path
    """The .npz file to write (a Minari dataset goes beside it: OUT with the suffix .minari; a LeRobot
    dataset is the folder OUT)."""
    format: Literal["npz", "minari", "both", "lerobot"] = "npz"
    """npz: the .npz file; minari: a Minari dataset folder (Farama's offline-RL format; needs the minari
    package), the same episodes; both: the two; lerobot: a LeRobotDataset v3 folder (Hugging Face
    LeRobot's format, docs/datasets.md; needs pyarrow)."""
    env: str = "tsrl/UR5ePickPlace-v0"
    """Environment id (ignored with --policy)."""
    obs: str = ""
    """Observation preset or spec of the agent that will train on the demonstrations (default: the
    task's own, as `tsrl train` and gym.make use it)."""
    action: str = "task"
    """Action mode: the task's own (task), or a built-in mode its solver acts in (taskspace, ...)."""
    episodes: int = 100
    """Episodes to keep."""
    policy: Annotated[Path | None, arg(metavar="RUN_DIR")] = None
    """Record this run's latest usable policy instead of a scripted controller."""
    seed: int = 0
    """Seed of the episode seeds."""
    keep_failed: bool = False
    """Keep unsuccessful episodes too."""
    camera: Annotated[str | None, arg(metavar="NAME")] = None
    """With --format lerobot: also this camera's frames as video, the episodes replayed and rendered
    (a camera of the task's model, or workspace: the view `tsrl render` uses without --camera)."""

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise InvalidConfig(f"--episodes must be >= 1; got {self.episodes}")
        if self.camera is not None and self.format != "lerobot":
            raise InvalidConfig(
                f"--camera: video goes into a LeRobot dataset (--format lerobot); got --format {self.format}"
            )

    def run(self) -> int:
        from .agents.demo_files import save_demos, summary_line
        from .agents.demo_lerobot import import_pyarrow, save_lerobot
        from .agents.demo_minari import import_minari, minari_path
        from .agents.demonstrators import record_demos
        from .agents.lerobot_video import check_camera

        paths = {
            "npz": [self.out],
            "minari": [minari_path(self.out)],
            "both": [self.out, minari_path(self.out)],
        }
        if self.format == "lerobot":
            import_pyarrow()  # missing: one line before the episodes run
            # The layout and task file of the env the episodes are recorded on go into the dataset.
            run = load_config(self.policy) if self.policy is not None else None
            source = TrainConfig(env_id=self.env, obs=self.obs, action=self.action) if run is None else run
            if self.camera is not None:
                check_camera(source, self.camera)  # unknown: one line before the episodes run
        elif self.format != "npz":
            import_minari()
        demos = record_demos(
            self.env, self.episodes, self.obs, self.action, self.policy, self.seed, self.keep_failed
        )
        if self.format == "lerobot":
            print(summary_line(demos, save_lerobot(demos, self.out, source, self.camera)))
            return 0
        for path in paths[self.format]:
            print(summary_line(demos, save_demos(demos, path)))
        return 0


#: Every `tsrl` command; a new one is a dataclass with run() and an entry here.
COMMANDS: dict[str, Callable[..., Any]] = {
    "train": Train,
    "evaluate": Evaluate,
    "render": Render,
    "plot": Plot,
    "show": Show,
    "demos": Demos,
    **EXPERIMENT_COMMANDS,
    **ROBOT_COMMANDS,
    **DEPLOY_COMMANDS,
}


#: Old command names, kept for one release: listed last in --help, each says so when it runs.
DEPRECATED_COMMANDS: dict[str, Callable[..., Any]] = {"demo": Demo}


class CliError(TsrlError):
    """Command-line input that tyro rejected, as one line."""


@contextlib.contextmanager
def _one_line_errors() -> Iterator[None]:
    """tyro's parse errors (a multi-line panel by default) as one CliError line."""
    with tyro._errors.on_parse_error(_raise_one_line):
        yield


def _raise_one_line(event: tyro._errors.ParseErrorEvent) -> None:
    e = tyro._errors
    see = f"see {event.prog} --help"
    if isinstance(event, e.InvalidChoice):
        message = (
            f"invalid value {event.value!r} for {_name(event.argument)}; accepted: {', '.join(event.choices)}"
        )
    elif isinstance(event, e.InstantiationFailure):
        where = f"{_name(event.argument)}: " if event.argument is not None else ""
        message = where + " ".join(event.message.split())
    elif isinstance(event, e.UnrecognizedArgs):
        message = f"unrecognized arguments: {' '.join(event.tokens)}; {see}"
    elif isinstance(event, e.MissingArgs):
        message = f"missing {', '.join(_name(a.arg) for a in event.missing_arguments)}; {see}"
    elif isinstance(event, e.MissingSubcommand):
        message = f"missing command; accepted: {', '.join(event.subcommand_spec.parser_from_name)}"
    elif isinstance(event, e.BadValue):
        message = f"bad value for {_name(event.argument)}; {see}"
    else:
        message = f"invalid arguments ({type(event).__name__}); {see}"
    raise CliError(message)


def _name(argument: Any) -> str:
    """An option's flags (--her/--her-relabel), or a positional argument's metavar (RUN_DIR)."""
    if argument.is_positional():
        return argument.lowered.metavar or argument.display_name()
    return argument.display_name()


def parse(argv: Sequence[str] | None = None) -> Command:
    """The command `argv` (default: sys.argv[1:]) asks for, its options validated."""
    argv = list(sys.argv[1:] if argv is None else argv)
    with _one_line_errors():
        command = tyro.extras.subcommand_cli_from_dict(
            COMMANDS | DEPRECATED_COMMANDS, args=argv, prog="tsrl", description=__doc__.split("\n\n")[0]
        )
    if isinstance(command, Train) and command.resume is not None:
        command = command.with_run_config(argv[1:])
    elif isinstance(command, Train) and command.config.agent.learner != "paper":
        command = command.with_learner(argv[1:])
    return command


def main(argv: Sequence[str] | None = None) -> int:
    try:
        return parse(argv).run()
    except TsrlError as err:
        print(f"tsrl: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C before a command catches it itself (start-up), or a second one
        print("tsrl: interrupted", file=sys.stderr)
        return 128 + signal.SIGINT


def _check_env_options(cfg: TrainConfig) -> None:
    """Makes (and closes) one environment so that a bad obs spec fails before torch loads."""
    import gymnasium as gym

    gym.make(cfg.gym_id, **cfg.env_kwargs).close()


def _differences(ours: Any, theirs: Any, prefix: str = "") -> list[str]:
    """Dotted paths of the leaf fields where two configs differ."""
    out = []
    for f in dataclasses.fields(ours):
        a, b = getattr(ours, f.name), getattr(theirs, f.name)
        if dataclasses.is_dataclass(a):
            out += _differences(a, b, f"{prefix}{f.name}.")
        elif a != b:
            out.append(prefix + f.name)
    return out


def _train_flags() -> dict[str, tuple[str, ...]]:
    """`tsrl train`'s option strings by TrainConfig field path, as tyro builds them from the
    dataclasses: {"agent.demos.batch_share": ("--demos-batch-share",), "env_id": ("--env", ...)}."""
    import warnings

    # get_parser is tyro's one view of its flags (deprecated, kept through the pinned 1.0 series).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        parser = tyro.extras.get_parser(Train, prog="tsrl train")
    prefix = "config."
    return {
        action.dest.removeprefix(prefix).replace("-", "_"): tuple(action.option_strings)
        for action in parser._actions
        if action.dest.startswith(prefix)
    }


def _given(options: tuple[str, ...], argv: Sequence[str]) -> str:
    """The option string among `options` that `argv` used (--demos or --demos-path, --no-x), else all."""
    for token in argv:
        name = token.split("=", 1)[0]
        if name in options:
            return name
    return "/".join(options)


if __name__ == "__main__":
    sys.exit(main())
