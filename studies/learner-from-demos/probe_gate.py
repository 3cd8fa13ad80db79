"""What the fast learner's acting gate measured (tsrl.agents.acting_gate): per run folder, from its
TensorBoard log, the mean of the gate's measured choice and clone success (each over its last 20
noise-free training episodes) and the share of episode ends at which the choice acted, per window of
env steps.

    python studies/learner-from-demos/probe_gate.py RUN [RUN ...] [--window 10000] [--until 70000]

Descriptive (a probe): the values are those the gate logged at each training episode's end.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

TAGS = ("gate/choice_success", "gate/clone_success", "gate/choice_acts")


def gate_scalars(run_dir: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{tag: (env steps, values)} of the gate's scalars in `run_dir`/tb (every event file)."""
    out: dict[str, tuple[list[float], list[float]]] = {tag: ([], []) for tag in TAGS}
    for events in sorted((run_dir / "tb").glob("events.out.tfevents.*")):
        log = EventAccumulator(str(events), size_guidance={"scalars": 0})
        log.Reload()
        for tag in TAGS:
            if tag in log.Tags()["scalars"]:
                for event in log.Scalars(tag):
                    out[tag][0].append(event.step)
                    out[tag][1].append(event.value)
    return {tag: (np.array(steps), np.array(values)) for tag, (steps, values) in out.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--window", type=int, default=10_000, help="env steps per row")
    parser.add_argument("--until", type=int, default=None, help="last env step read (default: all)")
    args = parser.parse_args()
    for run_dir in args.runs:
        scalars = gate_scalars(run_dir)
        last = max(float(steps.max()) for steps, _ in scalars.values() if steps.size)
        end = min(last, args.until) if args.until else last
        print(f"\n{run_dir.name}\n\n| env steps | choice measured | clone measured | choice acting (share) |")
        print("| --- | ---: | ---: | ---: |")
        for start in range(0, int(end), args.window):
            stop = min(start + args.window, end)
            cells = []
            for tag in TAGS:
                steps, values = scalars[tag]
                inside = (steps > start) & (steps <= stop)
                cells.append(f"{np.nanmean(values[inside]):.2f}" if inside.any() else "-")
            print(f"| {start:,}-{stop:,.0f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
