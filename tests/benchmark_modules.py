"""The scripts under benchmarks/, scripts/ and studies/<question>/ as modules for tests (they are
files, not a package)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]


def _load(folder: Path, name: str) -> ModuleType:
    """folder/<name>.py imported, with the folder on sys.path for its siblings."""
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_benchmark(name: str) -> ModuleType:
    """benchmarks/<name>.py imported, with benchmarks/ on sys.path for its siblings (`record`, ...)."""
    return _load(ROOT / "benchmarks", name)


def load_script(name: str) -> ModuleType:
    """scripts/<name>.py imported, with scripts/ on sys.path for its siblings."""
    return _load(ROOT / "scripts", name)


def load_study(question: str, name: str) -> ModuleType:
    """studies/<question>/<name>.py imported, with its folder on sys.path for its siblings."""
    return _load(ROOT / "studies" / question, name)
