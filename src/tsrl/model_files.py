"""Model files (MJCF, URDF) named by path, or inside an installed Python package as `pkg://<package>/<path>`.

A robot or task file may name a model that a package ships, without copying it::

    model = "pkg://gymnasium_robotics/envs/assets/fetch/reach.xml"

is the file `envs/assets/fetch/reach.xml` inside the installed package `gymnasium_robotics` (found
without importing the package); MuJoCo then reads the file where it lies, so its own `<include>`s,
meshes and textures resolve as they do for the package itself.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

from .exceptions import InvalidConfig

#: The prefix of a model inside an installed package.
PACKAGE_SCHEME = "pkg://"


def is_package_path(name: str) -> bool:
    """Whether `name` names a file inside an installed package (`pkg://<package>/<path>`)."""
    return name.startswith(PACKAGE_SCHEME)


def resolve_model_path(name: str, base: Path | None = None, key: str = "model") -> Path:
    """The file that `name` names: `pkg://<package>/<path>` inside the installed package, a relative
    path against `base` (the folder of the file that names it), else the path itself.

    Raises:
        InvalidConfig: a `pkg://` name whose package is not installed or lacks the file (the message
            names `key` and the package).
    """
    if not is_package_path(name):
        path = Path(name)
        return path if base is None or path.is_absolute() else base / path
    package, _, inner = name[len(PACKAGE_SCHEME) :].partition("/")
    if not package or not inner:
        raise InvalidConfig(f"{key} = {name!r}: accepted: {PACKAGE_SCHEME}<package>/<path inside it>")
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        raise InvalidConfig(f"{key} = {name!r}: no installed package {package!r} (pip install it first)")
    for location in spec.submodule_search_locations:
        path = Path(location) / inner
        if path.is_file():
            return path
    raise InvalidConfig(f"{key} = {name!r}: package {package!r} has no file {inner!r}")
