"""The `tsrl` command line: train, evaluate, render, plot, demo.

`tsrl train`'s options are generated from the fields of tsrl.agents.TrainConfig (and its nested
AgentConfig and HerConfig): each field's attribute docstring is its help text, its type and default
those of the option. Bad input ends with one line on stderr naming what is accepted, exit code 2.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import inspect
import itertools
import sys
import textwrap
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal, NoReturn

import mujoco
import numpy as np

from .assets import SCENES, load_model
from .assets.ur5e import HOME_Q, JOINT_LIMITS
from .exceptions import InvalidConfig, TsrlError
from .kinematics import forward_kinematics


def demo(out_dir: Path, scene: str = "reach", n_random: int = 3, seed: int = 0) -> list[Path]:
    """Renders `scene` at the home pose and at `n_random` seeded random poses; returns the PNG paths."""
    from PIL import Image

    from .rendering import SceneRenderer

    model = load_model(scene)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    # Random poses near home (+-0.6 rad per joint) so that the arm stays in view above the table.
    poses = [("home", HOME_Q)] + [
        (f"random_{i}", np.clip(HOME_Q + rng.uniform(-0.6, 0.6, 6), *JOINT_LIMITS.T)) for i in range(n_random)
    ]
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    with SceneRenderer(model) as renderer:
        for name, q in poses:
            forward_kinematics(model, data, q)
            path = out_dir / f"{scene}_{name}.png"
            Image.fromarray(renderer.render(data)).save(path)
            paths.append(path)
    return paths


# -- options generated from config dataclasses ------------------------------------------------------
#: Nested config fields whose options get a prefix (HerConfig.strategy -> --her-strategy).
_PREFIXED = {"her", "demos"}
#: Extra option names.
_ALIASES = {"env_id": ["--env"], "agent.her.relabel": ["--her"], "agent.demos.path": ["--demos"]}


def attribute_docstrings(cls: type) -> dict[str, str]:
    """{field: docstring} from the string literal that follows each annotated field in `cls`'s source."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    body = tree.body[0].body  # type: ignore[attr-defined]
    docs = {}
    for node, nxt in itertools.pairwise(body):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(nxt, ast.Expr)
            and isinstance(nxt.value, ast.Constant)
            and isinstance(nxt.value.value, str)
        ):
            docs[node.target.id] = " ".join(nxt.value.value.split())
    return docs


def _config_options(cls: type, prefix: str = "") -> list[tuple[str, str, type, Any, str]]:
    """(dotted path, option, type hint, default, help) for every leaf field of config dataclass `cls`."""
    hints = typing.get_type_hints(cls)
    docs = attribute_docstrings(cls)
    default = cls()
    out = []
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        if dataclasses.is_dataclass(hint):
            sub_prefix = prefix + (f"{f.name}-" if f.name in _PREFIXED else "")
            out += [(f"{f.name}.{p}", o, h, d, s) for p, o, h, d, s in _config_options(hint, sub_prefix)]
        else:
            out.append(
                (
                    f.name,
                    prefix + f.name.replace("_", "-"),
                    hint,
                    getattr(default, f.name),
                    docs.get(f.name, ""),
                )
            )
    return out


def add_config_options(parser: argparse.ArgumentParser, cls: type) -> list[tuple[str, str]]:
    """Adds one option per leaf field of `cls` (defaults suppressed: only given options are set).

    Returns (dotted field path, argparse dest) pairs for building the config back.
    """
    paths = []
    for path, option, hint, default, doc in _config_options(cls):
        dest = "cfg__" + path.replace(".", "__")
        names = [f"--{option}"] + _ALIASES.get(path, [])
        kwargs: dict[str, Any] = {"dest": dest, "default": argparse.SUPPRESS}
        default_text = " ".join(map(str, default)) if isinstance(default, tuple) else default
        kwargs["help"] = f"{doc} (default: {default_text})".replace("%", "%%")
        if typing.get_origin(hint) is Literal:
            kwargs["choices"] = list(typing.get_args(hint))
            kwargs["metavar"] = "{" + ",".join(kwargs["choices"]) + "}"
        elif hint is bool:
            kwargs["action"] = argparse.BooleanOptionalAction
        elif type(None) in typing.get_args(hint):  # `str | None`: given means a value
            kwargs["type"] = next(t for t in typing.get_args(hint) if t is not type(None))
            kwargs["metavar"] = kwargs["type"].__name__.upper()
        elif typing.get_origin(hint) is tuple:
            kwargs["type"] = int
            kwargs["nargs"] = "+"
            kwargs["metavar"] = "N"
        else:
            kwargs["type"] = hint
            kwargs["metavar"] = hint.__name__.upper()
        parser.add_argument(*names, **kwargs)
        paths.append((path, dest))
    return paths


def config_from_args(cls: type, args: argparse.Namespace, paths: list[tuple[str, str]]) -> Any:
    """Builds (and validates) `cls` from the options given on the command line; the rest are defaults."""
    from .agents.config import from_dict

    data: dict[str, Any] = dataclasses.asdict(cls())
    for path, dest in paths:
        if hasattr(args, dest):
            node = data
            *parents, leaf = path.split(".")
            for p in parents:
                node = node[p]
            node[leaf] = getattr(args, dest)
    return from_dict(cls, data)


class _Parser(argparse.ArgumentParser):
    """Errors are one line on stderr (no usage block), exit code 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message}\n")


# -- commands --------------------------------------------------------------------------------------
def _cmd_train(args: argparse.Namespace, paths: list[tuple[str, str]]) -> int:
    # Validation first; torch and stable-baselines3 load only once the input is known to be good.
    from .agents.config import TrainConfig, check_env_id, load_config

    if args.resume is not None:
        load_config(args.resume)
        given = [f"--{o}" for p, o, *_ in _config_options(TrainConfig) if hasattr(args, _dest(p))]
        given = [g for g in given if g != "--total-timesteps"]
        if given:
            raise InvalidConfig(
                f"--resume continues a run with its own config.json; only --total-timesteps may be "
                f"given with it, got {', '.join(given)}"
            )
        total = getattr(args, _dest("total_timesteps"), None)
        if total is not None and total < 1:
            raise InvalidConfig(f"total_timesteps must be > 0; got {total}")
    else:
        check_env_id(getattr(args, _dest("env_id"), TrainConfig.env_id))
        cfg = config_from_args(TrainConfig, args, paths)
        _check_env_options(cfg)

    from .agents.training import TrainingInterrupted, resume, train

    try:
        if args.resume is not None:
            resume(args.resume, total_timesteps=total, progress_bar=args.progress)
        else:
            train(cfg, args.out_dir, progress_bar=args.progress)
    except TrainingInterrupted as stop:
        print(f"tsrl train: {stop}", file=sys.stderr)
        return 128 + stop.signum
    return 0


def _check_env_options(cfg: Any) -> None:
    """Makes (and closes) one environment so that a bad obs spec fails before torch loads."""
    import gymnasium as gym

    gym.make(cfg.env_id, **cfg.env_kwargs).close()


def _dest(path: str) -> str:
    return "cfg__" + path.replace(".", "__")


def _latest(run_dir: Path) -> Path:
    from .agents.checkpoint import latest_checkpoint
    from .agents.config import NotARunFolder

    checkpoint = latest_checkpoint(run_dir)
    if checkpoint is None:
        raise NotARunFolder(run_dir, "no checkpoint yet")
    return checkpoint


def evaluate_run(run_dir: Path, episodes: int, seed: int | None = None) -> dict[str, Any]:
    """Success rate and mean final distance of a run's latest checkpoint over `episodes` seeded episodes."""
    from .agents.config import load_config

    cfg = load_config(run_dir)  # bad input fails before torch loads
    checkpoint = _latest(run_dir)
    from .agents import ALGOS
    from .agents.checkpoint import load_policy, read_state
    from .agents.evaluation import Evaluator, eval_seeds

    model, normalizer = load_policy(checkpoint, ALGOS[cfg.agent.algo])
    evaluator = Evaluator(cfg, eval_seeds(cfg.seed if seed is None else seed, episodes))
    try:
        result = evaluator.evaluate(model, normalizer)
    finally:
        evaluator.close()
    return {"result": result, "env_steps": read_state(checkpoint).env_steps, "checkpoint": checkpoint}


def render_run(
    run_dir: Path, out: Path, episodes: int = 2, seed: int | None = None, size: tuple[int, int] = (480, 480)
) -> Path:
    """Writes a video of the run's latest policy (deterministic) off-screen; mp4, else GIF. Returns its path."""
    from .agents.config import load_config

    cfg = load_config(run_dir)  # bad input fails before torch loads
    checkpoint = _latest(run_dir)
    from .agents import ALGOS, make_env
    from .agents.checkpoint import load_policy
    from .agents.evaluation import eval_seeds

    model, normalizer = load_policy(checkpoint, ALGOS[cfg.agent.algo])
    kwargs = {"width": size[0], "height": size[1]} if cfg.is_tsrl_env else {}
    env = make_env(cfg, render_mode="rgb_array", **kwargs)
    frames = []
    try:
        for episode_seed in eval_seeds(cfg.seed if seed is None else seed, episodes):
            obs, _ = env.reset(seed=episode_seed)
            frames.append(env.render())
            done = False
            while not done:
                batch = {k: v[None] for k, v in obs.items()}
                if normalizer is not None:
                    batch = normalizer.normalize_obs(batch)
                action, _ = model.predict(batch, deterministic=True)
                obs, _, terminated, truncated, _ = env.step(action[0])
                frames.append(env.render())
                done = terminated or truncated
        fps = int(env.metadata.get("render_fps", 25))
    finally:
        env.close()  # closes the env's off-screen renderer
    return write_video(frames, Path(out), fps)


def write_video(frames: list[np.ndarray], out: Path, fps: int) -> Path:
    """mp4 through imageio-ffmpeg's bundled ffmpeg; a GIF next to it if that is unavailable."""
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() != ".gif":
        try:
            import imageio.v2 as imageio

            with imageio.get_writer(out, fps=fps, codec="libx264", macro_block_size=1, quality=7) as writer:
                for frame in frames:
                    writer.append_data(frame)
            return out
        except Exception as err:  # noqa: BLE001  (no ffmpeg: fall back to GIF)
            print(
                f"tsrl render: mp4 unavailable ({type(err).__name__}: {err}); writing a GIF", file=sys.stderr
            )
            out.unlink(missing_ok=True)
            out = out.with_suffix(".gif")
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    images[0].save(out, save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return out


def _parser() -> tuple[argparse.ArgumentParser, list[tuple[str, str]]]:
    from .agents.config import TrainConfig

    parser = _Parser(prog="tsrl", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p_train = commands.add_parser(
        "train",
        formatter_class=lambda prog: argparse.HelpFormatter(prog, max_help_position=34, width=110),
        help="train DDPG/TD3/SAC + HER into a self-describing, resumable run folder",
        description="Train an agent. The run folder <out-dir>/<env>__<obs>__<action>__<algo>__s<seed> gets "
        "config.json, progress.csv, tb/ (TensorBoard), checkpoints/ and learning_curve.png.",
    )
    paths = add_config_options(p_train, TrainConfig)
    p_train.add_argument("--out-dir", type=Path, default=Path("results"), help="parent of the run folder")
    p_train.add_argument(
        "--resume", type=Path, metavar="RUN_DIR", help="continue this run from its latest checkpoint"
    )
    p_train.add_argument(
        "--progress", action=argparse.BooleanOptionalAction, default=True, help="show a progress bar"
    )

    p_eval = commands.add_parser("evaluate", help="success rate and final distance of a run's latest policy")
    p_eval.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    p_eval.add_argument(
        "--episodes", type=int, default=50, help="deterministic episodes, each with its own seed"
    )
    p_eval.add_argument(
        "--seed", type=int, default=None, help="seed of the episode seeds (default: the run's)"
    )

    p_render = commands.add_parser("render", help="video of a run's latest policy, rendered off-screen")
    p_render.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    p_render.add_argument("--out", type=Path, default=Path("video.mp4"), help="mp4 (or .gif) file")
    p_render.add_argument("--episodes", type=int, default=2, help="episodes in the video")
    p_render.add_argument(
        "--seed", type=int, default=None, help="seed of the episode seeds (default: the run's)"
    )
    p_render.add_argument(
        "--size", type=int, nargs=2, default=(480, 480), metavar=("W", "H"), help="frame size"
    )

    p_plot = commands.add_parser("plot", help="learning curves (eval success vs env steps) of run folders")
    p_plot.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR")
    p_plot.add_argument("--out", type=Path, default=Path("learning_curve.png"), help="PNG file")

    p_demo = commands.add_parser("demo", help="render a scene at home and a few poses to PNG files")
    p_demo.add_argument("--out-dir", type=Path, default=Path("results/demo"), help="folder for the PNG files")
    p_demo.add_argument("--scene", default="reach", help=f"built-in scene: {', '.join(SCENES)}")
    p_demo.add_argument("--poses", type=int, default=3, help="number of random poses besides home")
    p_demo.add_argument("--seed", type=int, default=0, help="seed of the random poses")
    _add_demos_command(commands)
    from .experiments.cli import add_experiment_commands

    add_experiment_commands(commands)  # experiment, report: handled by args.handler
    return parser, paths


def _add_demos_command(commands: Any) -> None:
    """`tsrl demos record`: demonstration files for `tsrl train --demos FILE` (tsrl.agents.demos)."""
    p_demos = commands.add_parser("demos", help="record demonstration episodes for --demos")
    sub = p_demos.add_subparsers(dest="demos_command", required=True, parser_class=_Parser)
    p = sub.add_parser(
        "record",
        help="record a demonstrator's successful episodes into a .npz file",
        description="Records episodes of the environment's scripted controller (reach, pick-and-place) "
        "or of a trained run's policy (--policy); keeps the successful ones unless --keep-failed.",
    )
    p.add_argument("--env", default="tsrl/UR5ePickPlace-v0", help="environment id (ignored with --policy)")
    p.add_argument(
        "--obs", default="fs1", help="observation preset or spec of the agent that will train on it"
    )
    p.add_argument("--action", default="taskspace", help="action mode")
    p.add_argument("--episodes", type=int, default=100, help="episodes to keep")
    p.add_argument("--out", type=Path, required=True, help="the .npz file to write")
    p.add_argument("--policy", type=Path, metavar="RUN_DIR", help="record this run's latest policy")
    p.add_argument("--seed", type=int, default=0, help="seed of the episode seeds")
    p.add_argument("--keep-failed", action="store_true", help="keep unsuccessful episodes too")
    p.set_defaults(handler=_cmd_demos_record)


def _cmd_demos_record(args: argparse.Namespace) -> int:
    from .agents.demos import record_demos, save_demos, summary_line

    if args.episodes < 1:
        raise InvalidConfig(f"--episodes must be >= 1; got {args.episodes}")
    demos = record_demos(
        args.env, args.episodes, args.obs, args.action, args.policy, args.seed, args.keep_failed
    )
    print(summary_line(demos, save_demos(demos, args.out)))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser, paths = _parser()
    args = parser.parse_args(argv)
    try:
        if hasattr(args, "handler"):
            return args.handler(args)
        if args.command == "train":
            return _cmd_train(args, paths)
        if args.command == "evaluate":
            if args.episodes < 1:
                raise InvalidConfig(f"--episodes must be >= 1; got {args.episodes}")
            out = evaluate_run(args.run_dir, args.episodes, args.seed)
            r = out["result"]
            print(
                f"{args.run_dir} ({out['env_steps']} env steps): success rate {r.success_rate:.2f} "
                f"({round(r.success_rate * r.episodes)}/{r.episodes} episodes), "
                f"mean final distance {r.mean_final_distance:.4f} m"
            )
        elif args.command == "render":
            if args.episodes < 1:
                raise InvalidConfig(f"--episodes must be >= 1; got {args.episodes}")
            if min(args.size) < 16:
                raise InvalidConfig(f"--size must be at least 16 16; got {args.size[0]} {args.size[1]}")
            print(f"wrote {render_run(args.run_dir, args.out, args.episodes, args.seed, tuple(args.size))}")
        elif args.command == "plot":
            from .agents.plotting import plot_learning_curves
            from .agents.training import load_config

            for run_dir in args.run_dirs:
                load_config(run_dir)  # a clear error for a folder that is not a run
            print(f"wrote {plot_learning_curves(args.run_dirs, args.out)}")
        elif args.command == "demo":
            if args.poses < 0:
                parser.error(f"--poses must be >= 0; got {args.poses}")
            for path in demo(args.out_dir, args.scene, args.poses, args.seed):
                print(f"wrote {path}")
    except TsrlError as err:
        print(f"tsrl: error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
