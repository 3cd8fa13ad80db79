"""The one typed loader: a TOML (or JSON) table -> a frozen dataclass (task, robot, run and experiment files).

A dataclass's type hints are its file format:

- `str`; `int` (never a bool); `float` (an int is taken as a float; NaN and inf are refused); `bool`;
  `Path` (from a string);
- `Literal[...]` (one of its values), `X | Y` and `X | None` (None from JSON's null);
- `tuple[X, ...]` (a list of X), `tuple[X, Y, Z]` (a list of exactly that many);
- `Mapping[str, X]` (a table of any keys, each value an X; read-only);
- `Any` (the value as read, unchecked: for a file's free-form descriptive parts);
- a nested dataclass (a table, e.g. `[goal.position]`, or one of an array of tables).

Keys are checked against the dataclass's fields: an unknown key, a missing required one (a field
without a default), a value of the wrong type or a list of the wrong length is one line of
InvalidConfig that names the file and the key::

    tasks/my.toml: goal.position.center must have 3 entries; got 2
    arm.toml: unknown key 'tpc'; accepted: name, model, joints, tcp, home, actuators, suction
    tasks/my.toml: missing key 'center' in [goal.position]

Rules on values (ranges, names) stay in each dataclass's `__post_init__`; one such error raised
while a nested table is built is prefixed with its table: `x.toml: [agent] gamma must be in (0, 1]`.
A new kind of file costs one dataclass and no parser.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, Literal, TypeVar

from .exceptions import InvalidConfig, is_int, is_number

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

T = TypeVar("T", bound="DataclassInstance")
_NONE = type(None)


def read_toml(path: Path | str) -> dict[str, Any]:
    """The table of the TOML file `path`.

    Raises:
        InvalidConfig: the file cannot be read or is not valid TOML (one line naming the file).
    """
    path = Path(path)
    try:
        return tomllib.loads(path.read_text())
    except OSError as err:
        raise InvalidConfig(f"{path}: cannot read it: {err.strerror}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise InvalidConfig(f"{path}: not valid TOML: {err}") from None


def load_file(
    cls: type[T], path: Path | str, *, section: str | None = None, extra: Mapping[str, Any] | None = None
) -> T:
    """An instance of dataclass `cls` from the TOML file `path`.

    Args:
        section: the keys may sit under a table of this name (e.g. `[robot]`) instead of at the top level.
        extra: fields that do not come from the file (e.g. the file's own path); not accepted as keys.
    """
    table = read_toml(path)
    if section is not None and section in table:
        return load_table(cls, table[section], source=path, where=section, extra=extra)
    return load_table(cls, table, source=path, extra=extra)


def load_table(
    cls: type[T],
    table: Any,
    *,
    source: Path | str | None = None,
    where: str = "",
    extra: Mapping[str, Any] | None = None,
) -> T:
    """An instance of dataclass `cls` from a table (a dict from TOML or JSON), every value checked.

    Args:
        source: the file the table came from; every error message starts with it.
        where: the table's key path in its file ("" for the top level, e.g. "robot" for `[robot]`).
        extra: fields that do not come from the table; not accepted as keys.

    Raises:
        InvalidConfig: one line naming `source` and the key (see the module docstring).
    """
    try:
        return _build(cls, table, where, dict(extra or {}))
    except InvalidConfig as err:
        if source is None:
            raise
        raise InvalidConfig(f"{source}: {err}") from None


def _build(cls: type[T], table: Any, where: str, extra: dict[str, Any]) -> T:
    if not isinstance(table, dict):
        raise InvalidConfig(f"{where or 'the file'} must be a table; got {table!r}")
    fields = [f for f in dataclasses.fields(cls) if f.init and f.name not in extra]
    names = [f.name for f in fields]
    unknown = [key for key in table if key not in names]
    if unknown:
        raise InvalidConfig(f"unknown {_keys(unknown)}{_in(where)}; accepted: {', '.join(names)}")
    missing = [
        f.name
        for f in fields
        if f.name not in table
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise InvalidConfig(f"missing {_keys(missing)}{_in(where)}")
    hints = typing.get_type_hints(cls)
    kwargs = {
        key: _value(hints[key], value, f"{where}.{key}" if where else key) for key, value in table.items()
    }
    try:
        return cls(**kwargs, **extra)
    except InvalidConfig as err:  # a rule of __post_init__: say which table broke it
        if not where:
            raise
        raise InvalidConfig(f"[{where}] {err}") from None


def _keys(keys: list[str]) -> str:
    return ("key " if len(keys) == 1 else "keys ") + ", ".join(map(repr, keys))


def _in(where: str) -> str:
    return f" in [{where}]" if where else ""


def _value(hint: Any, value: Any, key: str) -> Any:
    """`value` checked (and converted: lists to tuples, ints to floats, tables to dataclasses) as `hint`."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any:
        return value
    if origin is Mapping:
        if not (isinstance(value, dict) and all(isinstance(k, str) for k in value)):
            raise InvalidConfig(f"{key} must be a table; got {value!r}")
        return MappingProxyType({k: _value(args[1], v, f"{key}.{k}") for k, v in value.items()})
    if origin in (typing.Union, types.UnionType):
        if value is None and _NONE in args:
            return None
        options = [a for a in args if a is not _NONE]
        fitting = [a for a in options if _fits(a, value)]
        if not fitting and len(options) > 1:
            raise InvalidConfig(f"{key} must be {' or '.join(map(_describe, options))}; got {value!r}")
        return _value((fitting or options)[0], value, key)
    if origin is Literal:
        if not any(type(value) is type(a) and value == a for a in args):
            raise InvalidConfig(f"{key} = {value!r}; accepted: {', '.join(map(repr, args))}")
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise InvalidConfig(f"{key} must be a list; got {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_value(args[0], v, f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise InvalidConfig(f"{key} must have {len(args)} entries; got {len(value)}")
        return tuple(_value(a, v, f"{key}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if isinstance(hint, type) and dataclasses.is_dataclass(hint):
        return _build(hint, value, key, {})
    if hint in _SCALARS:
        if not _fits(hint, value):
            raise InvalidConfig(f"{key} must be {_describe(hint)}; got {value!r}")
        if hint is float and not math.isfinite(value):
            raise InvalidConfig(f"{key} must be a finite number; got {value!r}")
        return hint(value) if hint in (float, Path) else value
    raise TypeError(f"tsrl.configs cannot load {key}: its type {hint!r} is none of those it knows")


def _fits(hint: Any, value: Any) -> bool:
    """Whether `value` has the shape of `hint` (picks the option of a union to check it against)."""
    origin = typing.get_origin(hint)
    if origin is Literal:
        return any(type(value) is type(a) for a in typing.get_args(hint))
    if origin is tuple:
        return isinstance(value, list | tuple)
    if dataclasses.is_dataclass(hint) or origin is Mapping:
        return isinstance(value, dict)
    return hint in _SCALARS and _SCALARS[hint][0](value)


def _describe(hint: Any) -> str:
    origin = typing.get_origin(hint)
    if origin is Literal:
        return "one of " + ", ".join(map(repr, typing.get_args(hint)))
    if origin is tuple:
        return "a list"
    if dataclasses.is_dataclass(hint) or origin is Mapping:
        return "a table"
    return _SCALARS[hint][1] if hint in _SCALARS else repr(hint)


#: The scalar types a field may have: whether a value is one, and the words for it in an error.
_SCALARS: dict[type, tuple[Callable[[Any], bool], str]] = {
    int: (is_int, "an integer"),
    float: (is_number, "a number"),
    bool: (lambda v: isinstance(v, bool), "true or false"),
    str: (lambda v: isinstance(v, str), "a string"),
    Path: (lambda v: isinstance(v, str | Path), "a path (a string)"),
}


__all__ = ("load_file", "load_table", "read_toml")
