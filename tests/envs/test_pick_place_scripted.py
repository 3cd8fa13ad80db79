"""Pick-and-place is solvable on both arms: the scripted solver (tsrl.envs.solvers.PickPlaceSolver,
reading task maps on the environment's state), recording through tsrl.agents.demonstrators, succeeds
in >= 95 of 100 seeded episodes."""

import pytest

from tsrl.agents.demonstrators import record_demos


@pytest.mark.parametrize("env_id", ["tsrl/UR5ePickPlace-v0", "tsrl/PandaPickPlace-v0"])
def test_scripted_controller_solves_pick_and_place(env_id):
    demos = record_demos(env_id, episodes=100, obs="fs1", keep_failed=True)
    assert demos.meta["attempted"] == 100 and demos.meta["demonstrator"] == "scripted-pick-place"
    successes = int(demos.is_success[:, -1].sum())
    assert successes >= 95, f"{successes}/100 episodes succeeded"
