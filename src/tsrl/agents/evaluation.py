"""A policy's deterministic rollouts on seeded episodes: its success rate, final distance and share of
penalised episodes (Evaluator, evaluate_run), on its own task or on another of the same layout,
perturbed or not (tsrl.agents.transfer), and a video of it (render_run).

Success and distance are measured against the true goal: where the task reports
info["true_success"] / info["true_distance"] (a `[randomize]` goal_offset shows the policy a moved
goal), those count, else info["is_success"] / info["distance"].
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from ..envs.registration import TASK_ENV_ID
from ..exceptions import InvalidConfig
from .checkpoint import Checkpoint, load_policy, usable_checkpoint
from .config import TrainConfig
from .factory import ALGO_CLASSES, make_env
from .run_folder import NotARunFolder, run_config
from .transfer import EvalTask, check_layout, eval_task, target_env

#: Evaluation seeds are drawn from a stream of their own, apart from training's episode seeds.
_EVAL_STREAM = 0xE7A1
#: The stream of evaluations after training (experiments' [[evaluate]] arms): goals no training
#: evaluation has seen.
_FRESH_STREAM = 0xE7A2


@dataclass(frozen=True)
class EvalResult:
    success_rate: float
    """Fraction of episodes whose last step has info["true_success"] where the env reports it (a
    goal_offset perturbation), else info["is_success"]."""
    mean_final_distance: float
    """Mean of info["true_distance"] (else info["distance"]) at the last step [m] (NaN if the env
    reports neither)."""
    episodes: int
    penalised_rate: float = float("nan")
    """Fraction of episodes with a penalised step (info["penalty"] not 0, e.g. touching an obstacle);
    NaN if the env reports no penalty."""


class EvaluationStopped(Exception):
    """Evaluator.evaluate's `stop` answered True between two steps (a signal came): no result."""


def eval_seeds(seed: int, n: int) -> list[int]:
    """The seeds of a run's n evaluation episodes: fixed for the run, different across run seeds."""
    return [int(s) for s in np.random.SeedSequence(entropy=seed, spawn_key=(_EVAL_STREAM,)).generate_state(n)]


def fresh_eval_seeds(seed: int, n: int) -> list[int]:
    """Seeds of n evaluation episodes after training, apart from those of training's evaluations."""
    return [
        int(s) for s in np.random.SeedSequence(entropy=seed, spawn_key=(_FRESH_STREAM,)).generate_state(n)
    ]


class Evaluator:
    """Runs `len(seeds)` episodes side by side (one batched policy call per step), deterministically.

    On the run's own task, or on `task` (another task of the same layout, or a perturbed one) under
    the run's observation and action. Owns its environments: call close() when done.
    """

    def __init__(self, cfg: TrainConfig, seeds: list[int], task: EvalTask | None = None):
        self.seeds = list(seeds)
        self.envs: list[gym.Env] = [
            make_env(cfg) if task is None else gym.make(TASK_ENV_ID, **task.env_kwargs(cfg))
            for _ in self.seeds
        ]

    def evaluate(
        self,
        model: BaseAlgorithm,
        normalizer: VecNormalize | None,
        stop: Callable[[], bool] | None = None,
        on_step: Callable[[int, dict[str, Any]], None] | None = None,
    ) -> EvalResult:
        """The result over every episode; raises EvaluationStopped where `stop()` is True before a step
        (training asks it between steps, so SIGTERM never waits for thousands of episodes to end).
        `on_step(i, info)`, where given, sees each step's info of episode i (seeds[i]), in step order."""
        observations = [env.reset(seed=s)[0] for env, s in zip(self.envs, self.seeds, strict=True)]
        active = list(range(len(self.envs)))
        success = np.zeros(len(self.envs), dtype=bool)
        distance = np.full(len(self.envs), np.nan)
        penalised = np.zeros(len(self.envs), dtype=bool)
        reports_penalty = False
        while active:
            if stop is not None and stop():
                raise EvaluationStopped
            batch: Any = {key: np.stack([observations[i][key] for i in active]) for key in observations[0]}
            if normalizer is not None:
                batch = normalizer.normalize_obs(batch)
            actions, _ = model.predict(batch, deterministic=True)
            still = []
            for i, action in zip(active, actions, strict=True):
                observations[i], _, terminated, truncated, info = self.envs[i].step(action)
                if on_step is not None:
                    on_step(i, info)
                if "penalty" in info:
                    reports_penalty = True
                    penalised[i] |= info["penalty"] != 0
                if terminated or truncated:
                    success[i] = bool(info.get("true_success", info.get("is_success", False)))
                    distance[i] = float(info.get("true_distance", info.get("distance", np.nan)))
                else:
                    still.append(i)
            active = still
        mean_distance = float(np.mean(distance)) if np.all(np.isfinite(distance)) else float("nan")
        penalised_rate = float(np.mean(penalised)) if reports_penalty else float("nan")
        return EvalResult(float(np.mean(success)), mean_distance, len(self.envs), penalised_rate)

    def close(self) -> None:
        for env in self.envs:
            env.close()


@dataclass(frozen=True)
class RunEvaluation:
    """evaluate_run's answer: the result, which checkpoint it is of, and the task it ran on."""

    result: EvalResult
    env_steps: int
    checkpoint: Path
    task: str = ""
    """The evaluated task's name (the env id or task file's name, with its perturbation)."""


def load_run_policy(run_dir: Path) -> tuple[TrainConfig, BaseAlgorithm, VecNormalize | None, Checkpoint]:
    """Config, model and normaliser of a run's newest usable checkpoint, and that checkpoint.

    A damaged checkpoint is skipped with a warning (tsrl.agents.checkpoint.usable_checkpoint). The
    config is the run's on its recorded task, with a notice per changed file (tsrl.agents.task_record).
    """
    cfg = run_config(run_dir)
    checkpoint = usable_checkpoint(run_dir, cfg.agent.normalize, for_training=False)
    if checkpoint is None:
        raise NotARunFolder(run_dir, "no checkpoint yet")
    model, normalizer = load_policy(checkpoint, ALGO_CLASSES[cfg.agent.algo])
    return cfg, model, normalizer, checkpoint


def evaluate_run(
    run_dir: Path,
    episodes: int,
    seed: int | None = None,
    env_id: str | None = None,
    task: str | Path | None = None,
) -> RunEvaluation:
    """Success rate and mean final distance of a run's newest usable checkpoint over `episodes` seeded
    episodes (seeds from `seed`, by default the run's training-evaluation seeds), on its own task, on
    `env_id` (a registered id) or on `task` (a task file) of the same layout: a layout that differs is
    one line of InvalidConfig naming the first differing row or part, raised before the policy loads."""
    target = eval_task(run_config(run_dir, notify=False), target_env(env_id, task))
    return evaluate_run_on(run_dir, [target], episodes, seed)[0]


def evaluate_run_on(
    run_dir: Path, tasks: list[EvalTask], episodes: int, seed: int | None = None, fresh: bool = False
) -> list[RunEvaluation]:
    """evaluate_run on each of `tasks` (e.g. tsrl.agents.transfer.sweep's), in order: every layout
    checked first, the policy loaded once, every task on the same episode seeds (paired). `fresh`:
    seeds no training evaluation used (fresh_eval_seeds), else the training evaluation's (eval_seeds)."""
    cfg = run_config(run_dir, notify=False)
    for t in tasks:
        check_layout(cfg, t)
    cfg, model, normalizer, checkpoint = load_run_policy(run_dir)
    seeds = (fresh_eval_seeds if fresh else eval_seeds)(cfg.seed if seed is None else seed, episodes)
    steps = checkpoint.state.env_steps
    return [
        RunEvaluation(evaluate_policy(cfg, model, normalizer, t, seeds), steps, checkpoint.path, t.name)
        for t in tasks
    ]


def evaluate_policy(
    cfg: TrainConfig, model: BaseAlgorithm, normalizer: VecNormalize | None, task: EvalTask, seeds: list[int]
) -> EvalResult:
    """One evaluation of a loaded policy on `task` over the episodes of `seeds`."""
    evaluator = Evaluator(cfg, seeds, task)
    try:
        return evaluator.evaluate(model, normalizer)
    finally:
        evaluator.close()


def render_run(
    run_dir: Path,
    out: Path,
    episodes: int = 2,
    seed: int | None = None,
    size: tuple[int, int] = (480, 480),
    camera: str | None = None,
) -> Path:
    """Writes a video of the run's newest usable policy (deterministic), rendered off-screen from
    `camera` (a camera of the task's model; None: the task's workspace camera); mp4, else GIF.
    Returns its path. An unknown camera raises UnknownName listing the model's cameras."""
    cfg, model, normalizer, _ = load_run_policy(run_dir)
    if camera is not None and not cfg.is_tsrl_env:
        raise InvalidConfig(f"--camera names a camera of a tsrl task's model; {cfg.env_id} is not one")
    kwargs: dict[str, Any] = {"width": size[0], "height": size[1], "camera": camera}
    env = make_env(cfg, render_mode="rgb_array", **(kwargs if cfg.is_tsrl_env else {}))
    frames = []
    try:
        for episode_seed in eval_seeds(cfg.seed if seed is None else seed, episodes):
            obs, _ = env.reset(seed=episode_seed)
            frames.append(env.render())
            done = False
            while not done:
                obs, _, terminated, truncated, _ = env.step(policy_action(model, normalizer, obs))
                frames.append(env.render())
                done = terminated or truncated
        fps = int(env.metadata.get("render_fps", 25))
    finally:
        env.close()  # closes the env's off-screen renderer
    return write_video(frames, Path(out), fps)


def policy_action(
    model: BaseAlgorithm, normalizer: VecNormalize | None, obs: dict[str, np.ndarray]
) -> np.ndarray:
    """The policy's deterministic action (k,) for one observation dict, normalised as in training."""
    batch: Any = {k: v[None] for k, v in obs.items()}
    if normalizer is not None:
        batch = normalizer.normalize_obs(batch)
    action, _ = model.predict(batch, deterministic=True)
    return np.asarray(action[0])


def write_video(frames: list[Any], out: Path, fps: int) -> Path:
    """mp4 through imageio-ffmpeg's bundled ffmpeg; a GIF next to it if that is unavailable."""
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix.lower() != ".gif":
        try:
            import imageio.v2 as imageio

            writer: Any = imageio.get_writer(out, fps=fps, codec="libx264", macro_block_size=1, quality=7)
            with writer:
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
