"""studies/learner-from-demos/read_average.py: pre-registration 41's reading of probe_average.py's curves
(from the start on; the final as the mean of the last three; the rule's three parts)."""

from __future__ import annotations

from pathlib import Path

from benchmark_modules import load_study

reader = load_study("learner-from-demos", "read_average")


def _curve(path: Path, rows: list[tuple[int, float, float]]) -> Path:
    lines = ["env_steps,own,target,slow"] + [f"{s},{own:.4f},{own:.4f},{slow:.4f}" for s, own, slow in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_curve_is_read_from_its_start_and_its_final_is_the_mean_of_the_last_three(tmp_path):
    rows = [(0, 0.1, 0.9), (2_500, 0.3, 0.4), (5_000, 0.5, 0.5), (7_500, 0.6, 0.5), (10_000, 0.7, 0.9)]
    r = reader.read(_curve(tmp_path / "s0.csv", rows), "slow", 2_500)
    assert r.evaluations == 4 and r.ahead == 3  # 0 env steps left out; ties count as at or above
    assert abs(r.mean - (0.1 + 0.0 - 0.1 + 0.2) / 4) < 1e-9
    assert abs(r.second_half - (-0.1 + 0.2) / 2) < 1e-9  # after 5,000 (half of 10,000)
    assert abs(r.final_average - 1.9 / 3) < 1e-9 and abs(r.final_own - 1.8 / 3) < 1e-9
    assert (r.lowest_average, r.lowest_own) == (0.4, 0.3)


def test_the_rule_needs_four_runs_ahead_a_mean_gain_and_no_floor_lost(tmp_path):
    ahead = [(2_500, 0.5, 0.6), (5_000, 0.5, 0.6), (7_500, 0.5, 0.6)]
    behind = [(2_500, 0.5, 0.2), (5_000, 0.5, 0.5), (7_500, 0.5, 0.5)]
    runs = [reader.read(_curve(tmp_path / f"a{i}.csv", ahead), "slow", 2_500) for i in range(4)]
    met = reader.rule_41(runs + [reader.read(_curve(tmp_path / "b.csv", ahead), "slow", 2_500)], 0.244)
    assert all(part.endswith(": met") for part in met)
    parts = reader.rule_41(runs + [reader.read(_curve(tmp_path / "b.csv", behind), "slow", 2_500)], 0.244)
    assert parts[0].endswith("on 4 of 5 runs (needs 4): met")
    assert parts[1].startswith("mean final gain +0.060") and parts[1].endswith(": met")
    assert parts[2].endswith("['b']: not met")  # 0.2 under the average where the actor's lowest is 0.5
