"""A bounded, thread-safe hand-off from a driver thread to its consumer.

``put`` never blocks the driver: when the consumer falls behind, the oldest item is
dropped and counted. Use an instance directly as a driver's ``sink``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")


class Handoff(Generic[T]):
    """FIFO of at most ``capacity`` items; overwrite-oldest; waitable."""

    def __init__(self, capacity: int = 1024) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self._items: deque[T] = deque(maxlen=capacity)
        self._cond = threading.Condition()
        self.put_count = 0
        self.dropped = 0

    def __call__(self, item: T) -> None:
        self.put(item)

    def put(self, item: T) -> None:
        with self._cond:
            if len(self._items) == self._items.maxlen:
                self.dropped += 1
            self._items.append(item)
            self.put_count += 1
            self._cond.notify_all()

    def get(self, timeout: float) -> T | None:
        """The oldest item, waiting up to ``timeout`` s; None if none arrived."""
        with self._cond:
            if not self._cond.wait_for(lambda: len(self._items) > 0, timeout):
                return None
            return self._items.popleft()

    def drain(self) -> list[T]:
        """All queued items, oldest first (non-blocking)."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            return items

    def snapshot(self) -> list[T]:
        """The queued items without removing them."""
        with self._cond:
            return list(self._items)

    def wait_for(self, predicate: Callable[[list[T]], bool], timeout: float) -> bool:
        """Block until ``predicate(queued items)`` holds or ``timeout`` s pass."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate(list(self._items)):
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return False
                self._cond.wait(remaining)
            return True

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)
