"""Reads probe_average.py's curves as pre-registrations 40 and 41 read them: per run, from `--start`
env steps on, the slow (or target) average's evaluations against the actor's own on the same seeds,
and pre-registration 41's rule over the runs given.

- mean: the mean of (average - own) over the evaluations read; at or above: how many of them;
- second half: the mean of (average - own) over the evaluations after half the run's last env step;
- final: the mean of the last three evaluations (the issue's protocol), average / own;
- lowest: the lowest evaluation read, average / own, against the floor line `--line`.

    python studies/learner-from-demos/read_average.py CURVE.csv ... [--average slow] [--line 0.244]
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
from typing import NamedTuple

FINAL_EVALUATIONS = 3
"""The issue's final success: the mean of the last three evaluations."""
RULE_41_SEEDS_AHEAD = 4
"""Pre-registration 41: the average's final at or above the actor's on at least 4 of 5 seeds ..."""
RULE_41_MEAN_GAIN = 0.05
"""... its mean final at least 0.05 above the actor's ..."""


class Reading(NamedTuple):
    """One run's curve, read from its start on."""

    name: str
    mean: float
    ahead: int
    evaluations: int
    second_half: float
    final_average: float
    final_own: float
    lowest_average: float
    lowest_own: float


def read(curve: Path, average: str, start: int) -> Reading:
    """The reading of one curve (columns env_steps, own and the averages)."""
    with curve.open(newline="") as f:
        rows = [r for r in csv.DictReader(f) if int(r["env_steps"]) >= start]
    if len(rows) < FINAL_EVALUATIONS:
        raise SystemExit(f"{curve}: {len(rows)} evaluations from {start} env steps on; accepted: 3 or more")
    steps = [int(r["env_steps"]) for r in rows]
    own = [float(r["own"]) for r in rows]
    avg = [float(r[average]) for r in rows]
    gaps = [a - o for a, o in zip(avg, own, strict=True)]
    late = [g for g, s in zip(gaps, steps, strict=True) if s > steps[-1] / 2]
    return Reading(
        name=curve.stem,
        mean=sum(gaps) / len(gaps),
        ahead=sum(g >= 0 for g in gaps),
        evaluations=len(gaps),
        second_half=sum(late) / len(late),
        final_average=sum(avg[-FINAL_EVALUATIONS:]) / FINAL_EVALUATIONS,
        final_own=sum(own[-FINAL_EVALUATIONS:]) / FINAL_EVALUATIONS,
        lowest_average=min(avg),
        lowest_own=min(own),
    )


def rule_41(readings: list[Reading], line: float) -> list[str]:
    """Pre-registration 41's three parts, each 'met' or 'not met' with its numbers."""
    ahead = sum(r.final_average >= r.final_own for r in readings)
    gain = sum(r.final_average - r.final_own for r in readings) / len(readings)
    floor_lost = [r.name for r in readings if r.lowest_average < line <= r.lowest_own]
    verdict = {True: "met", False: "not met"}
    return [
        (
            f"final at or above the actor's on {ahead} of {len(readings)} runs (needs {RULE_41_SEEDS_AHEAD}): "
            f"{verdict[ahead >= RULE_41_SEEDS_AHEAD]}"
        ),
        f"mean final gain {gain:+.3f} (needs {RULE_41_MEAN_GAIN:+.2f}): {verdict[gain >= RULE_41_MEAN_GAIN]}",
        (
            f"runs whose lowest falls below the line {line} only under the average: {floor_lost or 'none'}: "
            f"{verdict[not floor_lost]}"
        ),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("curves", type=Path, nargs="+")
    parser.add_argument("--average", choices=("slow", "target"), default="slow")
    parser.add_argument("--start", type=int, default=2_500, help="env steps from which evaluations are read")
    parser.add_argument("--line", type=float, default=0.244, help="the floor line (BC's success - 0.05)")
    args = parser.parse_args()
    readings = [read(curve, args.average, args.start) for curve in args.curves]
    print(
        f"| run | {args.average} - own: mean | at or above own | second half | final: {args.average} / own "
        f"| lowest: {args.average} / own (line {args.line}) |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for r in readings:
        print(
            f"| {r.name} | {r.mean:+.3f} | {r.ahead} of {r.evaluations} | {r.second_half:+.3f} | "
            f"{r.final_average:.3f} / {r.final_own:.3f} | {r.lowest_average:.2f} / {r.lowest_own:.2f} |"
        )
    print("\nPre-registration 41's rule over these runs:")
    for part in rule_41(readings, args.line):
        print(f"- {part}")


if __name__ == "__main__":
    main()
