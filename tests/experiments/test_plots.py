"""Figure conventions (tsrl.experiments.plots): readable arm names, one colour per arm name in every
figure, titles naming the agent."""

from __future__ import annotations

from types import SimpleNamespace

from tsrl.experiments import plots


def _curves(*obs: str) -> list:
    return [SimpleNamespace(key=("tsrl/UR5eReach-v0", o, "taskspace", "ddpg", "")) for o in obs]


def test_labels_are_names_not_spec_strings_or_env_ids():
    assert plots.readable_label("fs1") == "fs1"
    assert plots.readable_label("fs1, distance(suction_cup, obstacle), accumulatedCollisions") == (
        "fs1 + obstacle distance + collisions"
    )
    three = "scalarProductXX(world, tcp), scalarProductYY(world, tcp), scalarProductZZ(world, tcp)"
    assert plots.readable_label(f"fs1, quaternion(tcp), {three}") == "fs1 + TCP quaternion + scalar products"
    assert plots.readable_label("fs0, velocity(position(tcp))") == "fs0 + TCP velocity"
    assert plots.readable_label("someMap(a, b)") == "someMap(a, b)"  # unknown terms stay as they are
    assert plots.readable_labels(["tsrl/UR5eReach-v0", "reach-joint-0.126"]) == [
        "task space",
        "joint 0.126 rad",
    ]
    assert plots.readable_labels(["tsrl/UR5eReach-v0", "tsrl/PandaReach-v0"]) == [
        "UR5eReach-v0",
        "PandaReach-v0",
    ]


def test_an_arm_keeps_its_colour_in_every_figure():
    spec = "fs1, distance(suction_cup, obstacle), accumulatedCollisions"
    alone = plots.colours(_curves("fs1", spec))
    beside_others = plots.colours(_curves("baseline", spec, "fs0"))
    assert alone[1] == beside_others[1] == plots.arm_colour("fs1 + obstacle distance + collisions")
    assert alone[0] == plots.PAPER_COLOURS["fs1"]
    # Two arms of one figure never share a colour while the palette has free ones.
    many = plots.colours(_curves(*(f"spec{i}" for i in range(len(plots.ARM_PALETTE)))))
    assert len(set(many)) == len(plots.ARM_PALETTE)


def test_titles_name_the_agent_with_its_demonstrations():
    info = {
        "algo": ["ddpg"],
        "agent": {"her": {"strategy": "final", "n_sampled_goal": 1}},
        "demos": {"episodes": 100},
    }
    assert plots.describe_agent(info) == "DDPG + HER (final, 1 relabelled copy) + 100 demonstrations"
    info = {"algo": ["ddpg"], "agent": {"her": {"strategy": "future", "n_sampled_goal": 4}}, "demos": None}
    assert plots.describe_agent(info) == "DDPG + HER (future, 4 relabelled copies)"
    curves = [
        SimpleNamespace(
            key=("tsrl/UR5ePickPlace-v0", "pick_phi", "taskspace", "ddpg", ""),
            seeds=(0, 1),
            eval_episodes=(50,),
        )
    ]
    assert plots.describe(curves, "DDPG + HER + 100 demonstrations") == (
        "UR5ePickPlace-v0, DDPG + HER + 100 demonstrations, 2 seeds, 50 eval episodes"
    )
