"""Atomic writes: a file (or folder) is written whole under a temporary name beside it, then renamed over
its path, so a reader, or a run resumed after a kill, sees the old version or the new one, never half."""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path


def temporary_name(path: Path, suffix: str = "") -> Path:
    """The temporary path a write of `path` goes through: hidden, in the same folder (a rename within a
    file system is atomic), named by this process (concurrent writers do not share it), ending in
    `suffix` (numpy's savez appends ".npz" to a name without it)."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp{suffix}")


@contextlib.contextmanager
def replacing(path: Path | str, suffix: str = "") -> Iterator[Path]:
    """Yields a temporary path to write; when the block ends normally it replaces `path` (a folder
    replaces the folder at `path`), when it raises it is removed and `path` is left as it was."""
    path = Path(path)
    tmp = temporary_name(path, suffix)
    _remove(tmp)  # a leftover of a killed process with this pid
    try:
        yield tmp
        if tmp.is_dir() and path.is_dir():
            shutil.rmtree(path)  # os.replace moves a folder only onto an empty one
        os.replace(tmp, path)
    except BaseException:
        _remove(tmp)
        raise


def write_atomic(path: Path | str, data: str | bytes) -> Path:
    """Writes `data` (text as UTF-8, or bytes) to `path` atomically; returns the path."""
    path = Path(path)
    with replacing(path) as tmp:
        if isinstance(data, str):
            tmp.write_text(data, encoding="utf-8")
        else:
            tmp.write_bytes(data)
    return path


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    else:
        path.unlink(missing_ok=True)
