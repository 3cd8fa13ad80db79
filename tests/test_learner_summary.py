"""studies/learner-from-demos/run.py summary: the issue's benchmark table in docs/results.md is what the
study's rows give, and its rules (every seed within the target, the floor line) read the rows right."""

from __future__ import annotations

from pathlib import Path

from benchmark_modules import load_study

ROOT = Path(__file__).resolve().parents[1]
study = load_study("learner-from-demos", "run")


def _block(text: str) -> list[str]:
    begin, end = text.index(study.SUMMARY_BEGIN), text.index(study.SUMMARY_END)
    return text[begin + len(study.SUMMARY_BEGIN) : end].strip().splitlines()


def test_the_results_page_shows_the_table_the_rows_give():
    assert _block((ROOT / "docs" / "results.md").read_text()) == study.summary()


def _row(arm: str, seed: int, final: float, to95: str, min_after: float, task: str = "PandaPush-v0") -> dict:
    return {"task": task, "arm": arm, "seed": str(seed), "final": str(final), "to95": to95,
            "min_after": str(min_after)}  # fmt: skip


def test_a_seed_past_the_target_or_below_the_line_is_counted():
    bc = [_row("bc100", s, 0.6, "", 0.0) for s in range(5)]
    fast = [_row("bound100", 0, 0.97, "17500.0", 0.7), _row("bound100", 1, 0.96, "32500.0", 0.56)]
    line = next(r for r in study.summary(bc + fast) if r.startswith("| PandaPush-v0 | 100 |"))
    assert line.endswith("| 0.60-0.60 | 0.97, 0.96 | 2 of 5 | 1 of 2 within 30,000 | yes: 0.56 (0.550) |")
    fast[1]["min_after"] = "0.549"
    line = next(r for r in study.summary(bc + fast) if r.startswith("| PandaPush-v0 | 100 |"))
    assert line.endswith("| no: 0.55 (0.550) |")


def test_tasks_without_the_preset_s_runs_say_so_and_10_demonstration_rows_have_no_target():
    rows = [_row("bc10", s, 0.2, "", 0.0) for s in range(5)] + [_row("bound10", 0, 0.5, "", 0.3)]
    table = study.summary(rows)
    assert "| PandaPush-v0 | 10 | 0.20-0.20 | 0.50 | 1 of 5 | no target | yes: 0.30 (0.150) |" in table
    assert "| PandaStack-v0 | 10 | - | not run | 0 of 5 | - | - |" in table
