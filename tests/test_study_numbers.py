"""scripts/study_numbers.py: the numbers a study README's result lines quote are checked against its
screens' data (re-derived comparisons, summary.md IQM cells, evaluations_summary.csv), at the decimals
they are quoted with; a wrong number, a number of another question's screen and a missing result
section are each reported."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))

import study_numbers


def _question(root: Path, name: str, screen: str, result: list[str] | None) -> Path:
    folder = root / name / screen
    folder.mkdir(parents=True)
    (folder / "results.csv").write_text("")
    (folder / "summary.md").write_text("| fs1 | 10 | 0.54 [0.42, 0.63] | 1.00 [0.92, 1.00] |\n")
    (folder / "evaluations_summary.csv").write_text(
        "label,success_iqm,success_ci_low,success_ci_high\nUR5e->Panda,0.976667,0.861667,0.995\n"
    )
    text = f"# {name}\n\n**Question.** ...\n"
    if result is not None:
        text += (
            "\n## Result\n"
            + "\n".join(result)
            + "\n\n## Command\n- quoted after the section: 9.99 [9.99, 9.99]\n"
        )
    (root / name / "README.md").write_text(text)
    return root / name


ROWS = [
    {"study": "screen-a", "effect": 0.351, "effect_ci_low": 0.159, "effect_ci_high": 0.507,
     "p": 0.00289, "p_holm": 0.00867, "p_holm_all": 0.133},
    {"study": "screen-b", "effect": 0.5, "effect_ci_low": 0.4, "effect_ci_high": 0.6,
     "p": 0.2, "p_holm": 0.4, "p_holm_all": 1.0},
]  # fmt: skip


def test_numbers_the_data_give_pass_at_their_decimals(tmp_path):
    question = _question(
        tmp_path,
        "q",
        "screen-a",
        [
            "- fs1 > baseline: +0.35 [+0.16, +0.51] (Holm p = 0.009; across all: p = 0.13); +0.351 [+0.159, +0.507]",
            "- final success 1.00 [0.92, 1.00]; on the Panda 0.98 [0.86, 0.99] and 0.977 [0.862, 0.995]",
        ],
    )
    assert study_numbers.problems(question, ROWS) == []


def test_a_wrong_or_foreign_number_is_reported(tmp_path):
    question = _question(
        tmp_path,
        "q",
        "screen-a",
        [
            "- fs1 > baseline: +0.36 [+0.16, +0.51], p = 0.0029",
            "- another screen's effect: +0.50 [+0.40, +0.60], p = 0.4",
            "- fs1 0.54 [0.42, 0.64]",
        ],
    )
    found = study_numbers.problems(question, ROWS)
    assert [line.split(": ", 1)[1].split(" is ")[0] for line in found] == [
        "'+0.36 [+0.16, +0.51]'",
        "'+0.50 [+0.40, +0.60]'",
        "'p = 0.4'",
        "'0.54 [0.42, 0.64]'",
    ]


def test_a_study_without_a_result_section_is_reported(tmp_path):
    question = _question(tmp_path, "q", "screen-a", None)
    assert study_numbers.problems(question, ROWS) == [f"{question / 'README.md'}: no '## Result' section"]
    assert study_numbers.check(ROWS, tmp_path) == [f"{question / 'README.md'}: no '## Result' section"]
