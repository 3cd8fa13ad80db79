"""Experiment definitions and statistics, without training: the shipped files load, malformed ones get
an error naming the bad field, the summary's statistics follow their stated rules."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from tsrl.agents.config import POLICY_INPUTS, AgentConfig, HerConfig, TrainConfig
from tsrl.exceptions import InvalidConfig
from tsrl.experiments.aggregate import compare, markdown_summary, sort_key, summarize
from tsrl.experiments.config import (
    Comparison,
    ExperimentConfig,
    config_labels,
    load_experiment,
    resolve_experiment,
)
from tsrl.experiments.curves import Curve, curves
from tsrl.experiments.results import variants

REPO = Path(__file__).resolve().parents[2]
GOOD = """
obs = ["fs1", "baseline"]
seeds = [0, 1]
total_timesteps = 300
eval_freq = 100
eval_episodes = 2

[agent]
learning_starts = 100
"""


@pytest.mark.parametrize(
    ("name", "runs", "budget"),
    [("quick-reach", 1, 5_000), ("paper-observations", 25, 8_000), ("action-ablation", 10, 20_000), ("pick-place", 6, 200_000),
     ("paper-observations-v2", 50, 6_000), ("action-ablation-v2", 40, 25_000), ("pose-features", 20, 50_000),
     ("paper-observations-v2-hard", 50, 8_000),
     ("obstacle-features", 20, 15_000), ("pick-place-features", 20, 50_000),
     ("pick-place-suction", 20, 50_000), ("pick-place-suction-ablation", 20, 50_000),
     ("pick-place-box-tcp", 20, 50_000), ("obstacle-features-v1", 20, 15_000)],
)  # fmt: skip
def test_shipped_definitions_load_and_expand(name, runs, budget, monkeypatch):
    monkeypatch.chdir(REPO)
    exp = load_experiment(resolve_experiment(name))
    configs = exp.runs()
    assert exp.name == name and len(configs) == runs
    assert len({c.run_name for c in configs}) == runs
    assert all(c.total_timesteps == budget and c.agent.algo == "ddpg" for c in configs)
    if name.endswith(("-v2", "-features")):  # the issue-16 study standard, with the paper's HER
        her = configs[0].agent.her
        assert len(exp.seeds) >= 10 and exp.eval_episodes >= 50 and exp.total_timesteps // exp.eval_freq >= 25
        assert exp.comparisons and (her.strategy, her.n_sampled_goal) == ("final", 1)
        inputs = ("observation", "desired_goal") if not name.startswith("pick-place") else POLICY_INPUTS
        assert configs[0].agent.policy_inputs == inputs


def test_grid_is_seed_major_and_carries_agent_overrides(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(GOOD)
    exp = load_experiment(path)
    assert [(c.obs, c.seed) for c in exp.runs()] == [("fs1", 0), ("baseline", 0), ("fs1", 1), ("baseline", 1)]
    assert all(c.agent.learning_starts == 100 and c.eval_episodes == 2 for c in exp.runs())


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("seed = [0]", ["unknown key 'seed'", "accepted: description, env, obs"]),
        ('obs = "fs1"\nobs_extra = 1', ["'obs_extra'"]),
        ("obs = 3", ["obs must be a list; got 3"]),
        ("seeds = 3", ["seeds must be a list; got 3"]),
        ("seeds = []", ["seeds must be a non-empty list; got []"]),
        ('seeds = [0, "1"]', ["seeds[1] must be an integer; got '1'"]),
        ("seeds = [0, true]", ["seeds[1] must be an integer; got True"]),
        ("seeds = [0, 0]", ["seeds lists 0 more than once"]),
        ("seeds = [-1]", ["seeds must be integers >= 0; got -1"]),
        ("total_timesteps = 1.5", ["total_timesteps must be an integer"]),
        ("eval_freq = 0", ["eval_freq must be > 0"]),
        ('algo = ["ppo"]', ["algo[0] = 'ppo'; accepted: 'ddpg', 'td3', 'sac'"]),
        ('algo = "sac"\nobs = "fs9"', ["obs 'fs9'"]),  # a single string is a one-value axis
        ('action = ["fly"]', ["unknown action 'fly'", "taskspace"]),
        ('obs = ["fs9"]', ["obs 'fs9'", "fs1"]),
        ('env = ["tsrl/Kitchen-v0"]', ["tsrl/Kitchen-v0", "tsrl/UR5eReach-v0"]),
        ("[agent]\nlr = 0.1", ["[agent]", "'lr'", "learning_rate"]),
        ("[agent]\ngamma = 2.0", ["[agent] gamma must be in (0, 1]"]),
        ('[agent]\nalgo = "td3"', ["[agent] algo is a grid axis"]),
        ("[agent.her]\nstrategy = 'past'", ["agent.her.strategy = 'past'; accepted: 'future', 'final'"]),
        ("[agent.her]\nn_sampled_goal = 0", ["[agent.her] her n_sampled_goal must be an integer >= 1"]),
        ("agent = 3", ["agent must be a table; got 3"]),
        ("obs = [", ["not valid TOML"]),
        ("[demos]\nepisodes = 0", ["[demos] episodes must be an integer >= 1; got 0"]),
        ("[demos]\nseed = 1", ["missing key 'episodes' in [demos]"]),
        ('[demos]\nepisodes = 5\n[agent.demos]\npath = "d.npz"', ["leave [agent.demos] path unset"]),
        (
            '[[budgets]]\nenv = "tsrl/PandaReach-v0"\ntotal_timesteps = 100',
            ["[budgets[0]] env", "not in the grid"],
        ),
        (
            '[[budgets]]\nenv = "tsrl/UR5eReach-v0"\ntotal_timesteps = 0',
            ["total_timesteps must be an integer >= 1"],
        ),
        ('[[budgets]]\nenv = "tsrl/UR5eReach-v0"', ["missing key 'total_timesteps' in [budgets[0]]"]),
        (
            '[[budgets]]\nenv = "tsrl/UR5eReach-v0"\ntotal_timesteps = 100\n' * 2,
            ["[budgets[1]] env 'tsrl/UR5eReach-v0' has a budget already"],
        ),
        (
            '[[budgets]]\nenv = "tsrl/UR5eReach-v0"\ntotal_timesteps = 100\n[[finetune]]\n'
            + 'from_env = "tsrl/UR5eReach-v0"\nenv = "tsrl/UR5eReach-v0"',
            ["[[budgets]] with [[finetune]]"],
        ),
        ('[[agents]]\nalgo = "td3"', ["[agents[0]] algo is a grid axis"]),
        ("[[agents]]\nlr = 0.1", ["'lr'", "agents[0]", "learning_rate"]),
        ("[[agents]]\n[[agents]]\nlayer_norm = 'critic'", ["two [[agents]] give one run folder name"]),
        (
            'action = ["joint"]\n[demos]\nepisodes = 5',
            ["[demos]", "got 'joint'", "taskspace or taskspace_orient"],
        ),
        (
            'env = ["tsrl/UR5ePoseReach-v0"]\naction = ["taskspace"]\n[demos]\nepisodes = 5',
            ["[demos]", "scripted-pose-reach solver", "its task's own action", "got 'taskspace'"],
        ),
    ],
)
def test_malformed_file_error_names_the_field_and_the_accepted_values(text, expected, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(text + "\n")
    with pytest.raises(InvalidConfig) as err:
        load_experiment(path)
    message = str(err.value)
    assert message.startswith(str(path)) and "\n" not in message
    for part in expected:
        assert part in message


def test_budgets_give_their_env_its_own_budget_and_evaluations(tmp_path):
    (tmp_path / "tasks").mkdir()
    task = tmp_path / "tasks" / "reach.toml"
    task.write_text((REPO / "experiments" / "tasks" / "reach-2cm.toml").read_text())
    path = tmp_path / "budgets.toml"
    path.write_text(
        'env = ["tsrl/UR5eReach-v0", "tsrl/PandaReach-v0", "tasks/reach.toml"]\nseeds = [0, 1]\n'
        "total_timesteps = 300\neval_freq = 100\n"
        '[[budgets]]\nenv = "tsrl/PandaReach-v0"\ntotal_timesteps = 600\neval_freq = 200\n'
        '[[budgets]]\nenv = "tasks/reach.toml"\ntotal_timesteps = 900\n'
    )
    exp = load_experiment(path)
    budgets = {(Path(c.env_id).name, c.seed): (c.total_timesteps, c.eval_freq) for c in exp.runs()}
    assert budgets == {
        (env, seed): budget
        for env, budget in (
            ("UR5eReach-v0", (300, 100)),
            ("PandaReach-v0", (600, 200)),
            ("reach.toml", (900, 100)),
        )
        for seed in (0, 1)
    }
    assert exp.arms() == ["tsrl/UR5eReach-v0", "tsrl/PandaReach-v0", "reach"]  # a budget is no variant


def test_agents_are_a_grid_axis_each_the_agent_table_with_its_changes(tmp_path):
    path = tmp_path / "agents.toml"
    path.write_text(
        GOOD
        + "[agent.demos]\nbc_weight = 0.5\n[demos]\nepisodes = 3\n"
        + "[[agents]]\n[[agents]]\nlearner = 'fast'\n[[agents]]\n[agents.demos]\nbatch_share = 0.0\n"
    )
    exp = load_experiment(path)
    runs = exp.runs()
    assert [(c.obs, c.seed, c.agent.learner) for c in runs[:3]] == [
        ("fs1", 0, "paper"),
        ("fs1", 0, "fast"),
        ("fs1", 0, "paper"),
    ]
    assert len(runs) == 12 and all(
        c.agent.learning_starts == 100 and c.agent.demos.bc_weight == 0.5 for c in runs
    )
    assert [c.agent.demos.active for c in runs[:3]] == [True, True, False]  # the third: no demonstrations
    assert [c.run_name.removeprefix("tsrl-UR5eReach-v0__fs1__taskspace__") for c in runs[:3]] == [
        "ddpg__s0__demos",
        "td3__s0__demos__fast__return-bound-1",
        "ddpg__s0",
    ]  # the fast learner's own algorithm where the grid gives none


def test_labels_leave_out_an_obs_or_action_that_goes_with_its_env():
    own = [("A", "fs1", "task", "ddpg", ""), ("B", "fs2", "task", "ddpg", "")]  # each task's own obs
    assert config_labels(own) == ["A", "B"]
    grid = [(env, obs, "task", "ddpg", "") for env in ("A", "B") for obs in ("fs1", "fs2")]
    assert config_labels(grid) == ["A / fs1", "A / fs2", "B / fs1", "B / fs2"]
    assert config_labels([("A", "fs1", "task", "ddpg", "")]) == ["fs1"]


def test_unknown_name_lists_the_known_experiments(monkeypatch):
    monkeypatch.chdir(REPO)
    with pytest.raises(InvalidConfig, match="unknown experiment 'quick'; known: .*quick-reach"):
        resolve_experiment("quick")
    assert resolve_experiment("quick-reach") == Path("experiments/quick-reach.toml")
    with pytest.raises(InvalidConfig, match="does not exist"):
        resolve_experiment("no/such.toml")


def _rows(seed: int, success: list[float], obs: str = "fs1") -> list[dict]:
    return [
        {"env": "tsrl/UR5eReach-v0", "obs": obs, "action": "taskspace", "algo": "ddpg", "variant": "", "seed": seed,
         "eval_episodes": 20, "env_steps": 500 * i, "episodes": 10 * i, "wall_time_s": 5.0 * i, "eval_success_rate": s}
        for i, s in enumerate(success)
    ]  # fmt: skip


def test_summary_censors_seeds_that_never_reach_a_threshold():
    # Sustained crossings (the mean of three consecutive evaluations from there on stays at the level):
    rows = (
        _rows(0, [0.0, 0.6, 0.95, 1.0, 1.0])  # means 0.52, 0.85, 0.98: 50% from 0, 90% and 95% from 1000
        + _rows(1, [0.0, 0.2, 0.55, 0.95, 0.9])  # means 0.25, 0.57, 0.80: 50% from 500, never 90%
        + _rows(2, [0.0, 0.1, 0.2, 0.3, 0.4])  # never: censored at 2000
        + _rows(0, [0.0, 0.0, 0.0, 0.0, 0.0], obs="baseline")
    )
    baseline, fs1 = summarize(sorted(rows, key=sort_key))  # Table I order
    assert (fs1["obs"], fs1["seeds"], fs1["final_env_steps"], fs1["final_evals"]) == ("fs1", 3, 2000, 3)
    assert (fs1["evaluations"], fs1["eval_episodes"]) == (5, "20")
    # Kaplan-Meier, 50%: S = 2/3 at 0, 1/3 at 500 -> 500 (the mean over reaching seeds says 250).
    assert fs1["seeds_reaching_50"] == 2 and fs1["env_steps_to_50_km_median"] == 500
    # 90% and 95%: one seed of three (1000), two censored at 2000: fewer than half known -> inf.
    assert fs1["seeds_reaching_90"] == 1 and fs1["env_steps_to_90_km_median"] == math.inf
    assert fs1["episodes_to_90_km_median"] == math.inf
    assert fs1["seeds_reaching_95"] == 1 and fs1["env_steps_to_95_km_median"] == math.inf
    # AUC: trapezoids of 500 steps over 2000: 1525 / 2000, 1075 / 2000, 400 / 2000; IQM of 3 = mean.
    assert fs1["auc_iqm"] == pytest.approx((0.7625 + 0.5375 + 0.2) / 3)
    assert fs1["auc_ci_low"] <= fs1["auc_iqm"] <= fs1["auc_ci_high"]
    finals = [np.mean([0.95, 1.0, 1.0]), np.mean([0.55, 0.95, 0.9]), np.mean([0.2, 0.3, 0.4])]
    assert fs1["final_success_iqm"] == pytest.approx(np.mean(finals))
    assert baseline["seeds_reaching_50"] == 0 and baseline["env_steps_to_50_km_median"] == math.inf
    assert baseline["wall_time_s_mean"] == 20.0


def test_the_final_penalised_share_is_summarised_compared_and_shown(tmp_path):
    def rows(seed: int, obs: str, penalised: list[float]) -> list[dict]:
        return [
            dict(r, eval_penalised_rate=p) for r, p in zip(_rows(seed, [0.2, 0.6, 0.9, 1.0], obs), penalised)
        ]

    fs1 = [[0.5, 0.3, 0.1, 0.0], [0.6, 0.2, 0.2, 0.1], [0.4, 0.1, 0.0, 0.0]]
    baseline = [[0.5, 0.5, 0.4, 0.5], [0.6, 0.4, 0.4, 0.3], [0.5, 0.6, 0.5, 0.4]]
    all_rows = [r for seed, p in enumerate(fs1) for r in rows(seed, "fs1", p)]
    all_rows += [r for seed, p in enumerate(baseline) for r in rows(seed, "baseline", p)]
    all_rows.sort(key=sort_key)
    summary = summarize(all_rows)
    finals = {name: [np.mean(p[-3:]) for p in arm] for name, arm in (("fs1", fs1), ("baseline", baseline))}
    assert summary[1]["final_penalised_iqm"] == pytest.approx(np.mean(finals["fs1"]))  # IQM of 3 = mean
    assert summary[0]["final_penalised_iqm"] == pytest.approx(np.mean(finals["baseline"]))
    (less,) = compare(
        curves(all_rows), (Comparison(a="fs1", b="baseline", metric="final_penalised", direction="less"),)
    )
    assert less["effect"] == pytest.approx(np.mean(finals["fs1"]) - np.mean(finals["baseline"]))
    assert less["poi"] == 0.0 and less["p"] == pytest.approx(0.05)  # every fs1 seed below every baseline seed
    table = markdown_summary(tmp_path, summary, [less], 1, [], [])
    assert "final penalised episodes, IQM" in table
    assert "final penalised" not in markdown_summary(
        tmp_path, summarize(sorted(_rows(0, [0.5, 1.0]), key=sort_key)), [], 0, [], []
    )


def _flat_curve(obs: str, levels: list[float]) -> Curve:
    """Seeds whose success stays at one level: AUC and final success equal that level."""
    steps = np.array([0, 500, 1000])
    return Curve(
        key=("tsrl/UR5eReach-v0", obs, "taskspace", "ddpg", ""),
        seeds=tuple(range(len(levels))),
        eval_episodes=(50,),
        env_steps=steps,
        success=np.repeat(np.array(levels)[:, None], 3, axis=1),
    )


def test_comparisons_report_effect_poi_holm_power_and_verdict():
    arms = [_flat_curve("fs1", [0.9, 0.7, 0.8]), _flat_curve("baseline", [0.1, 0.3, 0.2])]
    registered = (
        Comparison(a="fs1", b="baseline", metric="auc", direction="greater", min_effect=0.1),
        Comparison(a="baseline", b="fs1", metric="final_success", direction="greater"),
        Comparison(a="fs0", b="fs1"),  # no fs0 runs: counts in Holm's family as p = 1
        Comparison(a="fs2", b="fs1"),  # fs2 has one evaluation: no AUC, not computed, p = 1 in the family
    )
    one_eval = _flat_curve("fs2", [0.5, 0.6, 0.7])
    one_eval = dataclasses.replace(
        one_eval, env_steps=one_eval.env_steps[:1], success=one_eval.success[:, :1]
    )
    auc, final = compare([*arms, one_eval], registered)
    assert (auc["a"], auc["b"], auc["seeds_a"], auc["seeds_b"]) == ("fs1", "baseline", 3, 3)
    assert auc["effect"] == pytest.approx(0.6) and auc["effect_ci_low"] <= 0.6 <= auc["effect_ci_high"]
    assert auc["poi"] == 1.0
    # All three fs1 seeds above all three baseline seeds: one of C(6, 3) = 20 orderings -> p = 0.05;
    # Holm over four comparisons: 4 * 0.05 = 0.2. Three seeds cannot be detected at 0.05.
    assert auc["p"] == pytest.approx(0.05) and auc["p_holm"] == pytest.approx(0.2)
    assert auc["verdict"].startswith("no detectable difference at this power")
    assert final["p"] == pytest.approx(1.0) and final["p_holm"] == 1.0 and final["poi"] == 0.0
    assert auc["mde"] > 0


def test_variants_name_only_the_settings_that_differ():
    plain = TrainConfig(agent=AgentConfig(her=HerConfig(relabel="plain")), total_timesteps=99)
    assert variants([TrainConfig(seed=0), TrainConfig(seed=1, checkpoint_freq=7)]) == ["", ""]
    assert variants([TrainConfig(), plain]) == ["agent.her.relabel=feature", "agent.her.relabel=plain"]


COMPARED = """
obs = ["fs1", "baseline"]
[[comparisons]]
a = "fs1"
b = "baseline"
metric = "auc"
direction = "greater"
min_effect = 0.05
[[comparisons]]
a = "baseline"
b = "fs1"
metric = "final_success"
"""


def test_comparisons_are_parsed_with_their_defaults(tmp_path):
    path = tmp_path / "compared.toml"
    path.write_text(COMPARED)
    exp = load_experiment(path, check_envs=False)
    assert exp.arms() == ["fs1", "baseline"]
    assert exp.comparisons == (
        Comparison(a="fs1", b="baseline", metric="auc", direction="greater", min_effect=0.05),
        Comparison(a="baseline", b="fs1", metric="final_success", direction="greater", min_effect=None),
    )
    assert exp.to_dict()["comparisons"][0]["min_effect"] == 0.05  # goes to experiment.json for the report


@pytest.mark.parametrize(
    ("table", "expected"),
    [
        ('a = "fs9"\nb = "fs1"', "[comparisons[0]] unknown arm 'fs9'; accepted: fs1, baseline"),
        ('a = "fs1"\nb = "fs1"', "[comparisons[0]] compares arm 'fs1' with itself"),
        ('a = "fs1"', "missing key 'b' in [comparisons[0]]"),
        ('a = "fs1"\nb = "baseline"\nmetric = "steps"', "unknown metric 'steps'; accepted: auc, final_success, final_penalised"),
        ('a = "fs1"\nb = "baseline"\ndirection = "up"', "unknown direction 'up'; accepted: greater, less, two-sided"),
        ('a = "fs1"\nb = "baseline"\nmin_effect = -1', "min_effect must be a number > 0; got -1"),
        ('a = "fs1"\nb = "baseline"\nalpha = 0.1', "unknown key 'alpha' in [comparisons[0]]; accepted: a, b, metric"),
    ],
)  # fmt: skip
def test_bad_comparison_is_one_line_naming_the_accepted_values(table, expected, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(f'obs = ["fs1", "baseline"]\n[[comparisons]]\n{table}\n')
    with pytest.raises(InvalidConfig) as err:
        load_experiment(path, check_envs=False)
    assert str(err.value).startswith(f"{path}: ") and "\n" not in str(err.value)
    assert expected in str(err.value)


def test_arms_name_only_what_varies():
    exp = ExperimentConfig(name="x", obs=("fs1",), action=("taskspace", "joint"), algo=("ddpg", "sac"))
    assert exp.arms() == ["taskspace / ddpg", "taskspace / sac", "joint / ddpg", "joint / sac"]


def test_plot_colours_keep_the_papers_for_its_presets_and_give_others_unused_ones():
    import matplotlib.colors as mcolors

    from tsrl.experiments.plots import PAPER_COLOURS, colours

    def curves(*presets: str) -> list:
        return [SimpleNamespace(key=("tsrl/UR5eReach-v0", p, "taskspace", "ddpg", "")) for p in presets]

    paper = {mcolors.to_hex(c) for c in PAPER_COLOURS.values()}
    assert colours(curves("baseline", "simple", "fs0", "fs1", "fs2")) == list(PAPER_COLOURS.values())
    baseline, phi = colours(curves("baseline", "pick_phi"))
    assert baseline == PAPER_COLOURS["baseline"] and mcolors.to_hex(phi) not in paper
    many = [mcolors.to_hex(c) for c in colours(curves(*(f"spec{i}" for i in range(20))))]
    assert len(many) == 20 and not set(many) & paper  # tab20 less the paper's colours, cycled


def test_a_sustained_crossing_needs_three_evaluations_that_hold_the_level():
    from tsrl.experiments.curves import sustained_crossing

    steps = [0, 1, 2, 3, 4, 5]
    # One evaluation at 0.96 between lower ones does not count; the run holds 0.95 from step 2 on.
    assert sustained_crossing(steps, [0.5, 0.96, 0.97, 0.9, 0.99, 1.0], 0.95) == 2
    # A run at the level that falls back at its end never held it.
    assert math.isnan(sustained_crossing(steps[:4], [1.0, 1.0, 1.0, 0.5], 0.95))
    assert math.isnan(sustained_crossing(steps[:2], [1.0, 1.0], 0.95))  # fewer than three evaluations
    assert sustained_crossing(steps[:3], [0.9, 1.0, 1.0], 0.95) == 0  # the mean from the first on
