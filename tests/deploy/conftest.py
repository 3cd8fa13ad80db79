"""Exports for the deployment tests: policies built (not trained) with seeded normaliser statistics,
exported as `tsrl export` exports a run."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tsrl.agents import AgentConfig, TrainConfig


def build_export(
    out: Path,
    algo: str = "ddpg",
    env_id: str = "tsrl/UR5eReach-v0",
    obs: str = "fs1",
    seed: int = 0,
    limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None,
    **agent: Any,
) -> tuple[Path, Any, Any, TrainConfig]:
    """An untrained DDPG/TD3/SAC policy of `env_id` with random normaliser statistics, exported to
    `out` (`limits`: joint speed and acceleration limits for an arm that is not built in); returns
    (out, model, normalizer, config)."""
    from tsrl.agents.factory import make_agent, make_vec_env
    from tsrl.deploy.export import export_policy

    cfg = TrainConfig(
        env_id=env_id,
        obs=obs,
        seed=seed,
        total_timesteps=200,
        agent=AgentConfig(algo=algo, learning_starts=100, gradient_steps=10, batch_size=64, **agent),
    )
    venv = make_vec_env(cfg)
    model = make_agent(cfg, venv)
    rng = np.random.default_rng(seed)
    for rms in venv.obs_rms.values():  # statistics a run could have: folding them in must matter
        rms.mean = rng.normal(0.0, 0.3, rms.mean.shape)
        rms.var = rng.uniform(0.01, 2.0, rms.var.shape)
    venv.training = False
    export_policy(model, venv, cfg, out, None, *(limits or (None, None)))
    return out, model, venv, cfg


@pytest.fixture(scope="session")
def exports(tmp_path_factory: pytest.TempPathFactory) -> Callable[..., Path]:
    """export(name, **build_export kwargs) -> an export folder, built once per session per name."""
    made: dict[str, Path] = {}

    def export(name: str, **kwargs: Any) -> Path:
        if name not in made:
            made[name] = build_export(tmp_path_factory.mktemp(name) / "export", **kwargs)[0]
        return made[name]

    return export


@pytest.fixture(scope="session")
def ur5e_reach(exports: Callable[..., Path]) -> Path:
    return exports("ur5e_reach")


@pytest.fixture(scope="session")
def panda_pick_place(exports: Callable[..., Path]) -> Path:
    return exports("panda_pick_place", env_id="tsrl/PandaPickPlace-v0", obs="pick_phi_plus")


@pytest.fixture(scope="session")
def panda_pick_place_gripper(exports: Callable[..., Path]) -> Path:
    """The pick-and-place with the Franka Hand (a gripper dimension), on the task's own observation."""
    return exports("panda_pick_place_gripper", env_id="tsrl/PandaPickPlaceGripper-v0", obs="")


@pytest.fixture(scope="session")
def ur5e_reach_history(exports: Callable[..., Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The reach with its last 2 actions observed (a task file with `previous_actions = 2`)."""
    from tsrl.envs.tasks import load_task

    source = load_task("UR5eReach-v0").source
    assert source is not None
    task = tmp_path_factory.mktemp("history") / "reach-history.toml"
    task.write_text("previous_actions = 2\n" + source.read_text())
    return exports("ur5e_reach_history", env_id=str(task))
