"""MkDocs hook: links from a docs page to a file of the repository outside docs/ (a study's README, a
source file, an example), or to a folder without a README, must point at something that exists, or
the strict build fails; with `repo_url` set in mkdocs.yml they become links to it, otherwise the path
is shown as code (the site holds only docs/ pages and files). A folder with a README links to it. An
image of the repository outside docs/ (a study's figure) is copied into the site under _repo/ and shown;
a missing one fails the build too."""

from __future__ import annotations

import logging
import posixpath
import re
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File

log = logging.getLogger("mkdocs.plugins.tsrl_repo_links")
IMAGE = re.compile(r"!\[(?P<alt>[^\]]*)\]\((?P<target>[^)\s]+)\)")
SITE_COPY = "_repo"  # where images from outside docs/ go in the site
LINK = re.compile(r"(?<!!)\[(?P<text>[^\]]*)\]\((?P<target>[^)\s]+)\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def _rewrite(line: str, page_dir: str, repo: Path, docs: str, repo_url: str | None, page: str) -> str:
    def one(m: re.Match[str]) -> str:
        target = m["target"]
        if re.match(r"[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            return m[0]
        file, _, anchor = target.partition("#")
        path = posixpath.normpath(posixpath.join(docs, page_dir, file))  # relative to the repository
        if file.endswith("/") and not (repo / path).is_dir():
            log.warning("Doc file '%s' links to the folder '%s', which the repository lacks", page, target)
            return m[0]
        if (repo / path).is_dir() and (repo / path / "README.md").exists():
            path += "/README.md"  # a folder with its README, as GitHub shows it: the page
        inside_docs = path == docs or path.startswith(docs + "/")
        if inside_docs and not (repo / path).is_dir():  # a docs page or file: MkDocs checks it
            inside = posixpath.relpath(path, posixpath.join(docs, page_dir) if page_dir else docs)
            return (
                f"[{m['text']}]({inside}{'#' + anchor if anchor else ''})"  # e.g. ../../../docs/x.md -> x.md
            )
        if path.startswith("..") or not (repo / path).exists():
            log.warning("Doc file '%s' links to '%s', which is not a file of the repository", page, target)
            return m[0]
        if repo_url:
            kind = "tree" if (repo / path).is_dir() else "blob"
            return f"[{m['text']}]({repo_url.rstrip('/')}/{kind}/main/{path}{'#' + anchor if anchor else ''})"
        return f"{m['text']} (`{path}`)"

    return LINK.sub(one, line)


def _images(line: str, page_dir: str, repo: Path, docs: str, page: str, config: Any, files: Any) -> str:
    """`line` with each image outside docs/ pointing at its copy in the site (added to `files`)."""

    def one(m: re.Match[str]) -> str:
        target = m["target"]
        if re.match(r"[a-z][a-z0-9+.-]*:", target):
            return m[0]
        path = posixpath.normpath(posixpath.join(docs, page_dir, target))  # relative to the repository
        if path == docs or path.startswith(docs + "/"):
            return m[0]  # a docs file: MkDocs checks it
        if path.startswith("..") or not (repo / path).is_file():
            log.warning(
                "Doc file '%s' shows the image '%s', which is not a file of the repository", page, target
            )
            return m[0]
        src_uri = f"{SITE_COPY}/{path}"
        if files.get_file_from_path(src_uri) is None:
            files.append(File.generated(config, src_uri, abs_src_path=str(repo / path)))
        return f"![{m['alt']}]({posixpath.relpath(src_uri, page_dir or '.')})"

    return IMAGE.sub(one, line)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    repo = Path(config["config_file_path"]).parent
    docs = Path(config["docs_dir"]).relative_to(repo).as_posix()
    page_dir = posixpath.dirname(page.file.src_uri)
    out, fenced = [], False
    for line in markdown.split("\n"):
        if FENCE.match(line):
            fenced = not fenced
        out.append(
            line
            if fenced
            else _rewrite(
                _images(line, page_dir, repo, docs, page.file.src_uri, config, files),
                page_dir,
                repo,
                docs,
                config.get("repo_url"),
                page.file.src_uri,
            )
        )
    return "\n".join(out)
