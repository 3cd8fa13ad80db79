"""README.md stays a front page (issue 51): under 12,000 characters, and its task table lists exactly
the registered ids, each once, with the observation and action sizes gym.make gives; every page under
docs/ stays under 30,000 characters."""

from __future__ import annotations

import re
import warnings

import gymnasium as gym
from cli_runner import REPO

import tsrl

README = REPO / "README.md"
MARKER = "<!-- task-table:"
ROW = re.compile(r"^\| `(?P<id>tsrl/[^`]+)` \|")


def task_rows() -> dict[str, list[str]]:
    """id -> the row's cells, for the table under the task-table marker (the rows until a blank line)."""
    lines = README.read_text(encoding="utf-8").splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(MARKER))
    rows: dict[str, list[str]] = {}
    for line in lines[start + 3 :]:
        if not line.startswith("|"):
            break
        m = ROW.match(line)
        assert m, f"README.md: a task-table row that does not start with a `tsrl/...` id: {line}"
        assert m["id"] not in rows, f"README.md: {m['id']} twice in the task table"
        rows[m["id"]] = [cell.strip() for cell in line.strip("|").split("|")]
    return rows


def test_readme_is_under_12000_characters() -> None:
    assert len(README.read_text(encoding="utf-8")) < 12_000


def test_the_task_table_lists_exactly_the_registered_ids() -> None:
    assert list(task_rows()) == list(tsrl.ENV_IDS)


def test_the_task_tables_sizes_are_what_gym_make_builds() -> None:
    for env_id, cells in task_rows().items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # the v0 ids superseded by v1
            env = gym.make(env_id)
        obs, act = int(cells[3]), int(cells[4])
        assert (obs, act) == (env.observation_space["observation"].shape[0], env.action_space.shape[0]), (
            env_id
        )
        env.close()


def test_every_docs_page_is_under_30000_characters() -> None:
    long = {
        p.relative_to(REPO).as_posix(): n
        for p in (REPO / "docs").rglob("*.md")
        if (n := len(p.read_text(encoding="utf-8"))) >= 30_000
    }
    assert long == {}
