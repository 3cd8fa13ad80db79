"""Control-loop figures of `tsrl deploy`: the achieved rate, latency and jitter of each episode, from
the figures' definitions (tsrl.deploy.timing) and as the log and the summary give them."""

from __future__ import annotations

import itertools
import math

import pytest

from tsrl.cli import main
from tsrl.deploy.loop import read_log
from tsrl.deploy.timing import LoopTiming, worst_of


def test_the_figures_of_known_step_times():
    starts = [10.0, 10.04, 10.08, 10.13, 10.16]  # periods 40, 40, 50, 30 ms
    timing = LoopTiming.of(starts, [0.001, 0.003, 0.002, 0.004, 0.0025], control_period=0.04)
    assert timing.steps == 5 and timing.nominal_hz == pytest.approx(25.0)
    assert timing.rate_hz == pytest.approx(4 / 0.16)
    assert timing.jitter_ms == pytest.approx(math.sqrt(50.0))  # std of (40, 40, 50, 30) ms
    assert timing.worst_period_error_ms == pytest.approx(10.0)
    assert timing.latency_p50_ms == pytest.approx(2.5) and timing.latency_max_ms == pytest.approx(4.0)
    assert "rate 25.0 Hz (nominal 25), latency p50 2.50 ms, max 4.00 ms, jitter 7.07 ms" in timing.summary()
    slow = LoopTiming.of([0.0, 0.05, 0.1], [0.001, 0.009, 0.001], control_period=0.04)
    assert worst_of([timing, slow]).startswith(
        "loop over episodes: lowest rate 20.0 Hz (nominal 25), latency max 9.00 ms, largest jitter 7.07 ms"
    )
    one = LoopTiming.of([3.0], [0.001], control_period=0.04)  # one step: no period to measure
    assert math.isnan(one.rate_hz) and math.isnan(one.jitter_ms) and one.latency_max_ms == pytest.approx(1.0)


def test_deploy_logs_and_prints_each_episodes_figures(ur5e_reach, tmp_path, capsys):
    log = tmp_path / "deploy.jsonl"
    assert main(["deploy", str(ur5e_reach), "--episodes", "2", "--log", str(log)]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.startswith("episode ")]
    assert len(lines) == 2 and all("Hz (nominal 25), latency p50 " in line for line in lines)
    assert "; loop over episodes: lowest rate " in out and "(simulator unpaced; --realtime paces it)" in out
    _, records, episodes = read_log(log)
    for episode in episodes:
        cycles = [r for r in records if r["type"] == "cycle" and r["episode"] == episode["episode"]]
        assert len(cycles) == 50 and cycles[0]["wall_t"] == 0.0
        # The episode's figures are those of its logged step starts and latencies.
        expected = LoopTiming.of([r["wall_t"] for r in cycles], [r["latency_s"] for r in cycles], 0.04)
        logged = episode["timing"]
        assert logged["steps"] == 50 and logged["nominal_hz"] == pytest.approx(25.0)
        for key in ("rate_hz", "jitter_ms", "worst_period_error_ms", "latency_p50_ms", "latency_max_ms"):
            assert logged[key] == pytest.approx(getattr(expected, key), rel=1e-9, abs=1e-9), key
        # A step's latency ends with its first command, before its servo waits and the next step.
        for now, after in itertools.pairwise(cycles):
            assert 0 < now["latency_s"] < after["wall_t"] - now["wall_t"]
