"""The evaluation's penalised-episode share against the same policy's episodes counted one by one."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
from training_helpers import tiny

from tsrl.agents.evaluation import Evaluator, eval_seeds
from tsrl.agents.factory import make_agent, make_env, make_vec_env


def _penalised_episodes(cfg, model, seeds) -> list[bool]:
    env = make_env(cfg)
    touched = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        done, hit = False, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            hit |= info["penalty"] != 0
            done = terminated or truncated
        touched.append(hit)
    env.close()
    return touched


def test_evaluation_counts_the_episodes_with_a_penalised_step():
    # v0 places some obstacles on the robot, so an untrained policy touches in a few episodes.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        cfg = dataclasses.replace(
            tiny(),
            env_id="tsrl/UR5eObstacleReach-v0",
            obs="fs1, distance(suction_cup, obstacle), accumulatedCollisions",
        )
        model = make_agent(cfg, make_vec_env(cfg))
        seeds = eval_seeds(0, 30)
        evaluator = Evaluator(cfg, seeds)
        result = evaluator.evaluate(model, None)
        evaluator.close()
        touched = _penalised_episodes(cfg, model, seeds)
    assert 0 < sum(touched) < len(seeds)  # the check can fail either way
    assert result.penalised_rate == np.mean(touched)


def test_tasks_without_penalties_report_no_penalised_share():
    cfg = tiny()
    model = make_agent(cfg, make_vec_env(cfg))
    evaluator = Evaluator(cfg, eval_seeds(0, 2))
    result = evaluator.evaluate(model, None)
    evaluator.close()
    assert math.isnan(result.penalised_rate) and 0 <= result.success_rate <= 1
