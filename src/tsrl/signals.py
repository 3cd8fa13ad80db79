"""Signal handling: only the main thread may install a handler (Python's rule), so callers ask first."""

from __future__ import annotations

import threading


def in_main_thread() -> bool:
    """Whether this is the main thread (the only one that may install signal handlers)."""
    return threading.current_thread() is threading.main_thread()
