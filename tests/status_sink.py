"""A sink for a ZenohNode subscription that a test awaits on content (shared by the tests that watch the
daemon's ``dp/<vessel>/status``; importable as ``status_sink``: ``tests/`` is on ``sys.path`` through its
conftest)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any


class StatusSink:
    """Every validated message received (zenoh's thread puts them), awaited on content."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._items: list[dict[str, Any]] = []

    def put(self, received: Any) -> None:
        with self._cond:
            self._items.append(received.message)
            self._cond.notify_all()

    def latest(self) -> dict[str, Any] | None:
        with self._cond:
            return self._items[-1] if self._items else None

    def wait_for(self, predicate: Callable[[dict[str, Any]], Any], timeout_s: float) -> dict[str, Any] | None:
        """The first message received for which ``predicate`` holds, waiting up to ``timeout_s`` [s]; None if none."""
        found: list[dict[str, Any]] = []

        def match() -> bool:
            found[:] = [item for item in self._items if predicate(item)]
            return bool(found)

        with self._cond:
            return found[0] if self._cond.wait_for(match, timeout_s) else None
