"""Every relative link of README.md, docs/*.md, docs/results/**/*.md, studies/*/README.md and each
study screen's pages (studies/*/*/*.md) points at a file of the checkout,
and every #anchor at a heading of its page (GitHub's heading ids, which the docs site uses too:
mkdocs.yml's pymdownx.slugs.slugify). The docs site's strict build checks its own pages again
(`make docs`); this also covers the README and the studies, which live outside the site."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_runner import REPO

LINK = re.compile(r"\]\((?P<target>[^)\s]+)\)")
FENCE = re.compile(r"^(```|~~~)")
HEADING = re.compile(r"^#{1,6}\s+(?P<text>.+?)\s*$")
PAGES = [
    REPO / "README.md",
    REPO / "CHANGELOG.md",
    *sorted((REPO / "docs").glob("*.md")),
    *sorted((REPO / "studies").glob("*/README.md")),
    # each screen's pages beside its data (studies/<question>/<screen>/), and the benchmark data's
    *sorted(p for p in (REPO / "studies").glob("*/*/*.md") if (p.parent / "results.csv").is_file()),
    *sorted((REPO / "docs" / "results").rglob("*.md")),
]


def prose_lines(path: Path) -> list[str]:
    """The page's lines outside code fences."""
    lines, fenced = [], False
    for line in path.read_text(encoding="utf-8").splitlines():
        if FENCE.match(line):
            fenced = not fenced
        elif not fenced:
            lines.append(line)
    return lines


def slug(heading: str) -> str:
    """GitHub's id of a heading: markup dropped, lower case, punctuation but - and _ dropped, each space a -."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "").lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """The ids of `path`'s headings (a repeated heading gets -1, -2, ... as on GitHub)."""
    seen: dict[str, int] = {}
    out = set()
    for line in prose_lines(path):
        if m := HEADING.match(line):
            base = slug(m["text"])
            n = seen.get(base, 0)
            seen[base] = n + 1
            out.add(base if n == 0 else f"{base}-{n}")
    return out


def broken_links(path: Path, root: Path = REPO) -> list[str]:
    """One line per link of `path` (named relative to `root`) whose file or anchor is missing."""
    found = []
    for line in prose_lines(path):
        for m in LINK.finditer(line):
            target = m["target"]
            if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
                continue
            file, _, anchor = target.partition("#")
            dest = (path.parent / file).resolve() if file else path
            if not dest.exists():
                found.append(f"{path.relative_to(root)}: {target}: no such file")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                found.append(f"{path.relative_to(root)}: {target}: no such heading")
    return found


def test_slug_is_githubs() -> None:
    assert slug("Learner options and presets (issue 27): `--learner fast|paper`") == (
        "learner-options-and-presets-issue-27---learner-fastpaper"
    )
    assert slug("The paper's section VI, claim by claim") == "the-papers-section-vi-claim-by-claim"


def test_a_missing_file_and_a_missing_heading_are_reported(tmp_path: Path) -> None:
    (tmp_path / "guide.md").write_text("# Configuration\n")
    page = tmp_path / "page.md"
    page.write_text("# A b\n[x](#a-b) [y](#c) [z](nowhere.md) [w](guide.md#configuration) [v](guide.md#d)\n")
    assert broken_links(page, tmp_path) == [
        "page.md: #c: no such heading",
        "page.md: nowhere.md: no such file",
        "page.md: guide.md#d: no such heading",
    ]


@pytest.mark.parametrize("page", PAGES, ids=[p.relative_to(REPO).as_posix() for p in PAGES])
def test_every_link_resolves(page: Path) -> None:
    assert broken_links(page) == []
