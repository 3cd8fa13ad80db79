"""Probes' curves side by side: per progress.csv (a run's, or one kept in data/probe-curves), the mean
evaluation success over 40,000-80,000 env steps (or `--edges A B`: A-B) and over 80,000 (B) to the
last evaluation every file has, the lowest evaluation after 2,500, and the env steps reached.

    python studies/learner-from-demos/probe_windows.py CURVE.csv [CURVE.csv ...] [--edges A B]

Descriptive: the windows are those pre-registrations 19 and 20 read; a probe, not a screen.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import numpy as np

WINDOWS = (40_000, 80_000)  # env steps: the first window's ends; the second runs to the last common one
FLOOR_AFTER = 2_500  # env steps after which the floor rule reads evaluations


def curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(env steps, evaluation success) of a progress.csv."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return (
        np.array([float(r["env_steps"]) for r in rows]),
        np.array([float(r["eval_success_rate"]) for r in rows]),
    )


def window_mean(steps: np.ndarray, success: np.ndarray, start: float, end: float) -> float:
    """Mean success of the evaluations at env steps in [start, end]; nan where there is none."""
    inside = (steps >= start) & (steps <= end)
    return float(success[inside].mean()) if inside.any() else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("curves", type=Path, nargs="+")
    parser.add_argument("--edges", type=int, nargs=2, default=WINDOWS, metavar=("A", "B"))
    args = parser.parse_args()
    curves = {path: curve(path) for path in args.curves}
    common = min(float(steps[-1]) for steps, _ in curves.values())
    first, second = args.edges
    print(
        f"| curve | env steps reached | {first:,}-{second:,} | {second:,}-{common:,.0f} | lowest after {FLOOR_AFTER:,} |"
    )
    print("| --- | ---: | ---: | ---: | ---: |")
    for path, (steps, success) in curves.items():
        print(
            f"| {path.name} | {steps[-1]:,.0f} | {window_mean(steps, success, first, second):.3f} | "
            f"{window_mean(steps, success, second, common):.3f} | {success[steps >= FLOOR_AFTER].min():.2f} |"
        )


if __name__ == "__main__":
    main()
