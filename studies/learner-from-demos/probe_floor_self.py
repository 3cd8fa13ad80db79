"""The floor rule read on behaviour cloning itself: per task and number of demonstrations, the line
(BC's mean final minus 0.05) and BC's own final policies evaluated once on 100 fresh seeds
(data/runs.csv's `fresh`), with how many of them lie below it.

    python studies/learner-from-demos/probe_floor_self.py

A single 100-episode evaluation of a policy whose success is the floor's has a standard deviation of
about 0.05, as large as the rule's margin; this shows how often BC's own policies miss the line.
"""

from __future__ import annotations

from run import NEW_DEMOS, floor_line, read_rows


def main() -> None:
    rows = read_rows()
    print("| task | demos | line | BC's fresh evaluations (seeds 0-4) | below the line |")
    print("| --- | ---: | ---: | --- | ---: |")
    arms = sorted({(r["task"], r["arm"]) for r in rows if r["arm"].startswith("bc")})
    for task, arm in arms:
        suffix = NEW_DEMOS.get(task, "")
        if not arm.endswith(suffix) or arm.removeprefix("bc").removesuffix(suffix) not in ("10", "100"):
            continue  # arms of the task's old demonstrations
        bc = sorted((r for r in rows if (r["task"], r["arm"]) == (task, arm)), key=lambda r: int(r["seed"]))
        line = floor_line(rows, task, int(arm.removeprefix("bc").removesuffix(suffix)), suffix)
        fresh = [float(r["fresh"]) for r in bc]
        below = sum(f < line for f in fresh)
        cells = ", ".join(f"{f:.2f}" for f in fresh)
        print(f"| {task} | {arm.removeprefix('bc')} | {line:.3f} | {cells} | {below} of {len(fresh)} |")


if __name__ == "__main__":
    main()
