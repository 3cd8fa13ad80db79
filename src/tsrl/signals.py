"""Signal handling: only the main thread may install a handler (Python's rule), so callers ask first;
the stop signals of a long command (training, deployment) noted for it to honour at its next step."""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any, Self


def in_main_thread() -> bool:
    """Whether this is the main thread (the only one that may install signal handlers)."""
    return threading.current_thread() is threading.main_thread()


class StopSignals:
    """SIGINT and SIGTERM during the block (main thread only), noted: `caught` lists them and
    `on_signal(signum)` runs for each; a second SIGINT raises KeyboardInterrupt at once. The previous
    handlers come back when the block ends."""

    def __init__(self, on_signal: Callable[[int], None] = lambda signum: None):
        self.on_signal = on_signal
        self.caught: list[int] = []
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> Self:
        if in_main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self.previous[sig] = signal.signal(sig, self._note)
        return self

    def _note(self, signum: int, frame: Any) -> None:
        if self.caught and signum == signal.SIGINT:
            raise KeyboardInterrupt
        self.caught.append(signum)
        self.on_signal(signum)

    def __exit__(self, *exc: object) -> None:
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
