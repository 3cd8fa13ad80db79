"""Every ```python block of README.md and docs/*.md runs as a reader would run it.

Each block runs alone in a fresh interpreter (`python -c`), with the repository root as its working
directory (so `examples/...` paths resolve as in a checkout) and the environment's MUJOCO_GL.

A block that cannot run on its own is marked by an HTML comment on the line directly above its fence,
    <!-- docs-test: skip, <reason> -->
which the rendered page does not show; the reason is required, and every marked block is reported as
skipped with it. Keep these few: today they are a block that needs the user's own robot files of the
TOML blocks beside it (docs/robots.md; tests/envs/test_own_robot.py builds that arm) and one that
trains for minutes into ./results (docs/training.md; tests/agents train the same way, with small
budgets).

AFTER holds checks run after a block, in its namespace, for what a block shows beyond running.
"""

from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from cli_runner import REPO

FENCE = re.compile(r"^```python\s*$")
SKIP = re.compile(r"^<!-- docs-test: skip, (?P<reason>\S.*?) -->$")

#: (file, a line of the block) -> code run after it in its namespace.
AFTER = {
    # The map is evaluated on computed kinematics: tcp - target in world coordinates, nonzero.
    ("docs/index.md", 'y, J = tsrl.parse_spec("positionDiff(tcp, target)", model)(model, data)'): (
        "import numpy as np\n"
        "np.testing.assert_allclose(y, data.site('tcp').xpos - data.site('target').xpos)\n"
        "assert np.linalg.norm(y) > 0.01 and np.abs(J).max() > 0.01, (y, J)\n"
    ),
    # The quickstart's run trained to its budget and evaluated on the way.
    ("README.md", "run = train(TrainConfig("): (
        "import csv\n"
        "rows = list(csv.DictReader(open(run / 'progress.csv')))\n"
        "assert rows and int(rows[-1]['env_steps']) == 1000, rows[-1:]\n"
    ),
}


@dataclass(frozen=True)
class Block:
    path: Path
    line: int  # of the opening fence, 1-based
    code: str
    skip: str | None  # the reason, if marked

    @property
    def name(self) -> str:
        return f"{self.path.relative_to(REPO)}:{self.line}"


def python_blocks(path: Path) -> list[Block]:
    lines = path.read_text(encoding="utf-8").splitlines()
    blocks, i = [], 0
    while i < len(lines):
        if FENCE.match(lines[i]):
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            marker = SKIP.match(lines[i - 1]) if i > 0 else None
            blocks.append(
                Block(path, i + 1, "\n".join(lines[i + 1 : end]) + "\n", marker and marker["reason"])
            )
            i = end
        i += 1
    return blocks


DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
BLOCKS = [b for path in DOCS for b in python_blocks(path)]


def test_the_docs_have_python_blocks_and_each_skip_marker_is_on_one():
    assert len(BLOCKS) >= 7
    markers = [
        (path, n)
        for path in DOCS
        for n, line in enumerate(path.read_text().splitlines())
        if "docs-test:" in line
    ]
    marked = {(b.path, b.line - 2) for b in BLOCKS if b.skip}
    assert set(markers) == marked, "a docs-test marker not directly above a ```python fence, or misspelt"


@pytest.mark.parametrize("block", BLOCKS, ids=[b.name for b in BLOCKS])
def test_python_block_runs(block):
    if block.skip:
        pytest.skip(block.skip)
    checks = [
        code for (file, line), code in AFTER.items() if block.name.startswith(file) and line in block.code
    ]
    result = subprocess.run(
        [sys.executable, "-c", block.code + "".join(checks)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert result.returncode == 0, f"{block.name}\n{block.code}\n{result.stderr}"


def test_every_check_belongs_to_a_block():
    for file, line in AFTER:
        assert any(b.name.startswith(file + ":") and line in b.code for b in BLOCKS), (file, line)
