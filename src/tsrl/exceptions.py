"""Exceptions raised by tsrl; each message names the bad value and what is accepted."""

from __future__ import annotations

from collections.abc import Iterable
from typing import TypeGuard


class TsrlError(Exception):
    """Base class of every error tsrl raises on bad input."""


class UnknownScene(TsrlError, KeyError):
    """A scene name that is neither a built-in scene nor an existing MJCF file."""

    def __init__(self, name: str, known: Iterable[str]):
        super().__init__(
            f"unknown scene {name!r}; known scenes: {', '.join(sorted(known))} "
            "(or pass the path of an existing MJCF .xml file)"
        )

    def __str__(self) -> str:  # KeyError would quote the message
        return str(self.args[0])


class ModelLoadError(TsrlError, ValueError):
    """An MJCF file that MuJoCo cannot compile."""


class UnknownName(TsrlError, KeyError):
    """A joint, site, body or geom name the model does not have."""

    def __init__(self, kind: str, name: str, known: Iterable[str]):
        super().__init__(
            f"unknown {kind} {name!r}; the model's {kind}s: {', '.join(sorted(known)) or 'none'}"
        )

    def __str__(self) -> str:
        return str(self.args[0])


class UnknownTaskMap(TsrlError, KeyError):
    """A task-map (or preset) name the spec parser does not know."""

    def __init__(self, name: str, known: Iterable[str]):
        super().__init__(f"unknown task map {name!r}; known maps and presets: {', '.join(sorted(known))}")

    def __str__(self) -> str:
        return str(self.args[0])


class SpecError(TsrlError, ValueError):
    """A task-map spec string that cannot be parsed (syntax, argument count)."""


class InvalidAction(TsrlError, ValueError):
    """An action of the wrong shape, or with NaN/inf, rejected before it reaches the simulator."""


class InvalidConfig(TsrlError, ValueError):
    """A configuration value outside the accepted ones."""


class NotRelabelable(TsrlError, ValueError):
    """A task map whose value for a translated frame cannot be computed from its old value alone."""

    def __init__(self, spec: str, frame: str, reason: str):
        super().__init__(
            f"task map {spec} cannot be relabelled exactly when frame {frame!r} moves: {reason}; "
            "leave it out of the observation or add what it needs to the goal"
        )


def is_int(value: object) -> TypeGuard[int]:
    """Whether `value` is an int and not a bool (Python's True is an int; a config's true is not)."""
    return isinstance(value, int) and not isinstance(value, bool)


def is_number(value: object) -> TypeGuard[int | float]:
    """Whether `value` is an int or a float and not a bool."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def check_int(name: str, value: object, minimum: int) -> None:
    """Raises InvalidConfig unless `value` is an integer (not a bool) >= `minimum`, naming `name`."""
    if not is_int(value) or value < minimum:
        raise InvalidConfig(f"{name} must be an integer >= {minimum}; got {value!r}")


def check_positive(name: str, value: float, strict: bool = True) -> None:
    """Raises InvalidConfig unless `value` is a number > 0 (>= 0 with strict=False), naming `name`."""
    if not is_number(value):
        raise InvalidConfig(f"{name} must be a number; got {value!r}")
    if (strict and not value > 0) or (not strict and not value >= 0):
        raise InvalidConfig(f"{name} must be {'>' if strict else '>='} 0; got {value}")
