"""Re-renders every committed study (studies/<question>/<study>/) from its committed data, without training:
a folder with experiment.json through `tsrl report` (tables, comparisons, figures: it reads
results.csv when the run folders are absent); an early folder without one (superseded studies,
written by an older report) gets its figures only, learning_curves.png replacing the older
learning_curves_steps.png / learning_curves_episodes.png, and its markdown links follow.

    python scripts/rerender_results.py [study ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

from study_folders import ROOT, screen_folder, screen_folders

from tsrl.experiments.aggregate import CURVES_PNG, RESULTS_CSV, read_results, sort_key, write_report
from tsrl.experiments.config import EXPERIMENT_FILE
from tsrl.experiments.curves import curves
from tsrl.experiments.plots import plot_curves

OLD_FIGURES = ("learning_curves_steps.png", "learning_curves_episodes.png")


def rerender(folder: Path) -> list[Path]:
    """The folder's report or figures from its results.csv; returns the files written."""
    if (folder / EXPERIMENT_FILE).is_file():
        return write_report(folder)
    out = plot_curves(
        curves(sorted(read_results(folder / RESULTS_CSV), key=sort_key)), folder / CURVES_PNG, folder.name
    )
    for old in OLD_FIGURES:
        (folder / old).unlink(missing_ok=True)
    for md in folder.glob("*.md"):
        lines = md.read_text().splitlines(keepends=True)
        kept, linked = [], False
        for line in lines:
            if any(f"({old})" in line for old in OLD_FIGURES):
                if not linked:
                    kept.append(f"![success rate vs env steps; per-seed AUC]({CURVES_PNG})\n")
                    linked = True
                continue
            kept.append(line)
        md.write_text("".join(kept))
    return [out]


def main(argv: list[str]) -> int:
    folders = [screen_folder(name) for name in argv] or screen_folders()
    for folder in folders:
        for path in rerender(folder):
            print(f"wrote {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
