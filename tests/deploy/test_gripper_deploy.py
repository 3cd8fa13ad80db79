"""A gripper pick-and-place policy, cloned from the scripted demonstrations, exported and deployed on
the MuJoCo stand-in: its successes on `tsrl evaluate`'s seeds are evaluate's (the tool command, the
measured width and the rest of the step are the training environment's)."""

from __future__ import annotations

import pytest

from tsrl.cli import main

GRIPPER = "tsrl/PandaPickPlaceGripper-v0"
EPISODES = 10


@pytest.fixture(scope="module")
def cloned_run(tmp_path_factory):
    from tsrl.agents import TrainConfig, train
    from tsrl.agents.config import AgentConfig, DemoConfig
    from tsrl.agents.demo_files import save_demos
    from tsrl.agents.demonstrators import record_demos

    root = tmp_path_factory.mktemp("gripper")
    path = save_demos(record_demos(GRIPPER, 20, seed=0), root / "demos.npz")
    cfg = TrainConfig(
        env_id=GRIPPER,
        eval_freq=1000,
        eval_episodes=2,
        checkpoint_freq=1000,
        agent=AgentConfig(algo="bc", bc_steps=1000, demos=DemoConfig(path=str(path))),
    )
    return train(cfg, root / "runs", progress_bar=False)


def test_a_cloned_gripper_policy_deploys_with_evaluates_success_on_the_same_seeds(
    cloned_run, tmp_path, capsys
):
    from tsrl.agents.evaluation import eval_seeds, evaluate_run
    from tsrl.deploy.loop import read_log

    evaluated = evaluate_run(cloned_run, EPISODES, seed=7).result.success_rate
    assert main(["export", str(cloned_run), "--out", str(tmp_path / "export")]) == 0
    seeds = [str(s) for s in eval_seeds(7, EPISODES)]
    log = tmp_path / "deploy.jsonl"
    argv = ["deploy", str(tmp_path / "export"), "--episodes", str(EPISODES), "--seeds", *seeds]
    assert main([*argv, "--servo", "hold", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    _, records, episodes = read_log(log)
    deployed = sum(e["true_success"] for e in episodes) / EPISODES
    assert 0 < evaluated and deployed == evaluated, (deployed, evaluated)
    assert f"success {round(deployed * EPISODES)}/{EPISODES}" in out
    widths = {round(r["tool"], 6) for r in records if r["type"] == "cycle"}
    assert {0.0, 0.08} <= widths or len(widths) > 2  # the gripper was commanded to close and open
