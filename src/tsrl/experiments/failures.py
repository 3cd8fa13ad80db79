"""Failure classes of a trained object-moving policy (issue 24: "report the curve and what limits it"):
its final policy's deterministic episodes, each failed one put in one class by what the object did.

    python studies/manipulation-family/failure_modes.py RUN_DIR [RUN_DIR ...] [--episodes 100] [--save NAME]

Per run: the newest usable checkpoint's policy on `--episodes` fresh evaluation episodes (the seeds
`tsrl evaluate` uses, none seen in training's evaluations), the run's own task, observation and
action. The objects are the bodies whose positions are in the task's goal (`[goal] map =
"position(<body>)"`, several for a stack, "position(peg), quaternion(peg)" for the peg: its position
only); a goal of several objects gives one row per object ("run (box_b)"), each object's episodes
classed by its own position and goal, "success" meaning that object ended within the position
tolerance. Classes of an object's failed episode, in this order:

- *not moved*: the object never moved 1 cm from where it started;
- *reached, then lost*: it was within the success tolerance at some step but not at the last;
- *short of the goal*: it ended at most half as far from the goal as it started (moved the right
  way, too little);
- *moved, not towards the goal*: it moved, and ended more than half as far from the goal as it started.

Also per run: the median number of steps successful episodes took to first meet the tolerance; how
many failed episodes ended *stalled*: the TCP moved less than 1 mm over the last 10 steps (the
deterministic policy's action no longer moving it), where a policy still at work would move; and the
share of the policy's action components *at a bound* of the action space (within 0.5 % of its range
of either end: |a| >= 0.99 for [-1, 1]) over every step of every episode, a saturated deterministic
actor's mark (full steps and a fully open or closed hand); and how many *reached, then lost* episodes
ended with the object *touching the robot* (a MuJoCo contact between one of its geoms and a geom of the
robot's kinematic tree at the last step: carried off or pushed by the hand, rather than dropped or
left), and how many were *held when last at the goal* (touching the robot at the last step the object
was within the tolerance: it left the goal from the hand, rather than after it was put down); and of
the episodes whose goal was *lifted* (more than 1 cm above the object's start: in the air, not on the
table), how many there were, how many failed and how many were *reached, then lost*.
"""

from __future__ import annotations

import csv
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import mujoco
import numpy as np
from gymnasium import spaces

from ..agents.evaluation import fresh_eval_seeds, load_run_policy, policy_action
from ..agents.factory import make_env
from ..envs.base import TaskEnv
from ..taskmaps import resolve_frame

MOVED = 0.01  # m
LIFTED = 0.01  # m: a goal this far above the object's start is a lifted one
STALL_STEPS, STALL_MOVE = 10, 0.001  # steps, m
AT_BOUND = 0.005  # of the action range, from either end
#: The file of a saved measurement's rows (one per run and goal object).
DATA_CSV = "data.csv"
CLASSES = ("success", "not moved", "reached, then lost", "short of the goal", "moved, not towards the goal")


def goal_objects(env: TaskEnv) -> list[tuple[str, slice]]:
    """The bodies whose positions the goal holds, each with its slice of the desired goal
    ("position(box), position(box_b)" -> [("box", 0:3), ("box_b", 3:6)]; a quaternion part is skipped);
    ValueError for a goal without a position(<body>)."""
    spec = env.task.goal.map
    found, start = [], 0
    for part in (p.strip() for p in spec.split("),")):
        name, _, arg = part.rstrip(")").partition("(")
        width = 4 if name == "quaternion" else 3
        if name == "position" and arg and "," not in arg:
            found.append((arg, slice(start, start + 3)))
        elif name not in ("position", "quaternion"):
            found = []
            break
        start += width
    if not found:
        raise ValueError(
            f"{env.task.name}: goal map {spec!r}; failure classes need a goal of position(<body>) parts "
            "(with quaternion(<body>) parts skipped)"
        )
    return found


def classify(start: np.ndarray, path: np.ndarray, goal: np.ndarray, tolerance: float) -> str:
    """The class of one episode from the object's start (3,), its positions after each step (T, 3) and
    the goal (3,) [m, world frame]."""
    distance = np.linalg.norm(path - goal, axis=1)
    if distance[-1] <= tolerance:
        return "success"
    if np.max(np.linalg.norm(path - start, axis=1)) < MOVED:
        return "not moved"
    if np.any(distance <= tolerance):
        return "reached, then lost"
    if distance[-1] <= 0.5 * np.linalg.norm(start - goal):
        return "short of the goal"
    return "moved, not towards the goal"


def lifted(start: np.ndarray, goal: np.ndarray) -> bool:
    """Whether the goal (3,) lies more than LIFTED above the object's start (3,) [m, world z up]: a goal
    in the air rather than on the surface the object starts on."""
    return bool(goal[2] - start[2] > LIFTED)


def stalled(tcp_path: np.ndarray) -> bool:
    """Whether the TCP's positions after each step (T, 3) [m] stay within STALL_MOVE of where they
    were STALL_STEPS steps before the end, over those last steps (an episode shorter than that: False)."""
    if len(tcp_path) <= STALL_STEPS:
        return False
    last = tcp_path[-STALL_STEPS - 1 :]
    return bool(np.max(np.linalg.norm(last - last[0], axis=1)) < STALL_MOVE)


def at_bound(actions: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Which components of actions (..., A) lie within AT_BOUND of the range of either bound (A,) of the
    action space (a boolean array like actions)."""
    margin = AT_BOUND * (high - low)
    return (actions <= low + margin) | (actions >= high - margin)


def touches(model: mujoco.MjModel, data: mujoco.MjData, body: int, root: int) -> bool:
    """Whether a contact of `data` (the last collision pass: at the start of the last physics step) is
    between a geom of body `body` and a geom of a body in the kinematic tree rooted at body `root`."""
    for contact in data.contact[: data.ncon]:
        bodies = model.geom_bodyid[[contact.geom1, contact.geom2]]
        roots = model.body_rootid[bodies]
        if (bodies[0] == body and roots[1] == root) or (bodies[1] == body and roots[0] == root):
            return True
    return False


def failure_modes(
    run_dir: Path, episodes: int, describe: Callable[[dict[str, Any]], list[str]] | None = None
) -> list[dict[str, Any]]:
    """One row per goal object: the run (with what `describe` says of its config.json's dict, such as
    what sets a study's run apart that its name does not say, and the object's name where the goal
    has several), its env steps, per class the
    number of episodes, how many failed episodes ended stalled, how many reached-then-lost ones ended
    with the object touching the robot and how many were held when last at the goal, how many
    episodes had a lifted goal and how many of those failed or were reached then lost, and the share
    of action components at a bound (the run's, the same in each of its rows)."""
    cfg, model, normalizer, checkpoint = load_run_policy(run_dir)
    env = make_env(cfg)
    base = env.unwrapped
    assert isinstance(base, TaskEnv)
    objects = goal_objects(base)
    variant = describe(cfg.to_dict()) if describe is not None else []
    tolerance = base.task.success.position
    counts = [dict.fromkeys(CLASSES, 0) for _ in objects]
    stalls = [0 for _ in objects]
    lost_touching = [0 for _ in objects]
    lost_held = [0 for _ in objects]
    lifted_goals, failed_lifted, lost_lifted = ([0 for _ in objects] for _ in range(3))
    object_ids = [base.model.body(body).id for body, _ in objects]
    tcp = resolve_frame(base.model, "tcp")
    tcp_body = base.model.site_bodyid[tcp.id] if tcp.kind == "site" else tcp.id
    robot_root = int(base.model.body_rootid[tcp_body])
    tcp_positions = base.data.site_xpos if tcp.kind == "site" else base.data.xpos
    steps_to_success: list[list[int]] = [[] for _ in objects]
    assert isinstance(env.action_space, spaces.Box)
    low, high = env.action_space.low, env.action_space.high
    bounded, components = 0, 0
    for seed in fresh_eval_seeds(cfg.seed, episodes):
        obs, _ = env.reset(seed=seed)
        starts = [base.data.body(body).xpos.copy() for body, _ in objects]
        goal = np.asarray(obs["desired_goal"], dtype=float)
        paths: list[list[np.ndarray]] = [[] for _ in objects]
        tcp_path: list[np.ndarray] = []
        touching: list[list[bool]] = [[] for _ in objects]
        done = False
        while not done:
            action = policy_action(model, normalizer, obs)
            bounded += int(np.count_nonzero(at_bound(action, low, high)))
            components += action.size
            obs, _, terminated, truncated, _ = env.step(action)
            for path, (body, _) in zip(paths, objects, strict=True):
                path.append(base.data.body(body).xpos.copy())
            tcp_path.append(tcp_positions[tcp.id].copy())
            for touched, body_id in zip(touching, object_ids, strict=True):
                touched.append(touches(base.model, base.data, body_id, robot_root))
            done = terminated or truncated
        tcp_stalled = stalled(np.array(tcp_path))
        for i, (_, part) in enumerate(objects):
            positions = np.array(paths[i])
            kind = classify(starts[i], positions, goal[part], tolerance)
            counts[i][kind] += 1
            if lifted(starts[i], goal[part]):
                lifted_goals[i] += 1
                failed_lifted[i] += kind != "success"
                lost_lifted[i] += kind == "reached, then lost"
            stalls[i] += kind != "success" and tcp_stalled
            within = np.linalg.norm(positions - goal[part], axis=1) <= tolerance
            if kind == "reached, then lost":
                lost_touching[i] += touching[i][-1]
                lost_held[i] += touching[i][int(np.flatnonzero(within)[-1])]
            if kind == "success":
                steps_to_success[i].append(int(np.argmax(within)) + 1)
    env.close()
    return [
        {
            "run": _label(run_dir.name, [*variant, *([body] if len(objects) > 1 else [])]),
            "env_id": cfg.env_id,
            "env_steps": checkpoint.state.env_steps,
            "episodes": episodes,
            **count,
            "median_steps_to_success": float(np.median(steps)) if steps else float("nan"),
            "failed_stalled": stall,
            "lost_touching": ended_touching,
            "lost_held": held,
            "lifted_goals": n_lifted,
            "failed_lifted": n_failed,
            "lost_lifted": n_lost,
            "actions_at_bound": bounded / components,
        }
        for (body, _), count, steps, stall, ended_touching, held, n_lifted, n_failed, n_lost in zip(
            objects,
            counts,
            steps_to_success,
            stalls,
            lost_touching,
            lost_held,
            lifted_goals,
            failed_lifted,
            lost_lifted,
            strict=True,
        )
    ]


def _label(run: str, parts: list[str]) -> str:
    """`run (part, part)`, or `run` without parts."""
    return f"{run} ({', '.join(parts)})" if parts else run


def _always(rows: list[dict[str, Any]]) -> bool:
    """A column worth showing for any rows."""
    return True


def _some_goal_lifted(rows: list[dict[str, Any]]) -> bool:
    """Whether some row had a lifted goal (a push's never has: its column would be all zeros)."""
    return any(int(r["lifted_goals"]) > 0 for r in rows)


class OptionalColumn(NamedTuple):
    """A column after the median that data saved before it was measured lacks."""

    header: str
    keys: tuple[str, ...]  # the keys a row needs
    cell: Callable[[dict[str, Any]], str]
    worth_showing: Callable[[list[dict[str, Any]]], bool] = _always


#: Each shown only where every row has its keys and the rows make it worth showing.
OPTIONAL_COLUMNS: tuple[OptionalColumn, ...] = (
    OptionalColumn("failed, ended stalled", ("failed_stalled",), lambda r: f"{int(r['failed_stalled'])}"),
    OptionalColumn(
        "lost, ended touching the robot", ("lost_touching",), lambda r: f"{int(r['lost_touching'])}"
    ),
    OptionalColumn("lost, held when last at the goal", ("lost_held",), lambda r: f"{int(r['lost_held'])}"),
    OptionalColumn(
        "goal lifted: episodes, failed, reached then lost",
        ("lifted_goals", "failed_lifted", "lost_lifted"),
        lambda r: f"{int(r['lifted_goals'])}, {int(r['failed_lifted'])}, {int(r['lost_lifted'])}",
        _some_goal_lifted,
    ),
    OptionalColumn(
        "actions at a bound", ("actions_at_bound",), lambda r: f"{float(r['actions_at_bound']):.0%}"
    ),
)


def render(rows: list[dict[str, Any]]) -> list[str]:
    """The table (markdown) from `failure_modes`' rows (or their CSV strings); each of OPTIONAL_COLUMNS
    only where every row has it (data saved before it was measured has not) and it is worth showing
    (the lifted goals' only where some row had a lifted goal)."""
    shown = [
        c for c in OPTIONAL_COLUMNS if all(key in r for r in rows for key in c.keys) and c.worth_showing(rows)
    ]
    lines = [
        "| run | env steps | "
        + " | ".join(CLASSES)
        + " | median steps to success |"
        + "".join(f" {c.header} |" for c in shown),
        "| --- | ---: | " + " | ".join("---:" for _ in CLASSES) + " | ---: |" + " ---: |" * len(shown),
    ]
    for r in rows:
        n = int(r["episodes"])
        cells = " | ".join(f"{int(r[c])} ({int(r[c]) / n:.0%})" for c in CLASSES)
        median = float(r["median_steps_to_success"])
        lines.append(
            f"| `{r['run']}` | {int(r['env_steps']):,} | {cells} | {'-' if np.isnan(median) else f'{median:.0f}'} |"
            + "".join(f" {c.cell(r)} |" for c in shown)
        )
    return lines


def table(data_dir: Path) -> list[str]:
    """The table from a saved measurement's rows (`data_dir`/DATA_CSV)."""
    with open(data_dir / DATA_CSV, newline="") as f:
        return render(list(csv.DictReader(f)))
