"""A bounded, thread-safe hand-off from a driver thread to its consumer (a ring buffer).

``put`` never blocks the driver: when the consumer falls behind, the oldest item is
dropped and counted. Use an instance directly as a driver's ``sink``. The consumer
takes the oldest item (``get``), everything (``drain``), or only the newest
(``take_newest``: the older ones count as dropped, as for camera frames when the
processing cannot keep up).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

T = TypeVar("T")


@dataclass(frozen=True)
class HandoffStats:
    """Counters: items put, taken by the consumer, dropped (overwritten or skipped), queued."""

    capacity: int
    pushed: int
    taken: int
    dropped: int
    size: int


class Handoff(Generic[T]):
    """FIFO of at most ``capacity`` items; overwrite-oldest; waitable."""

    def __init__(self, capacity: int = 1024) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self._items: deque[T] = deque(maxlen=capacity)
        self._cond = threading.Condition()
        self.capacity = capacity
        self.put_count = 0
        self.dropped = 0
        self.taken = 0
        self._closed = False

    def __call__(self, item: T) -> None:
        self.put(item)

    def put(self, item: T) -> None:
        with self._cond:
            if len(self._items) == self._items.maxlen:
                self.dropped += 1
            self._items.append(item)
            self.put_count += 1
            self._cond.notify_all()

    def get(self, timeout: float | None) -> T | None:
        """The oldest item, waiting up to ``timeout`` s; None if none arrived (or closed)."""
        with self._cond:
            if not self._cond.wait_for(lambda: len(self._items) > 0 or self._closed, timeout) \
                    or not self._items:
                return None
            self.taken += 1
            return self._items.popleft()

    def take_newest(self, timeout: float | None) -> T | None:
        """The newest item, waiting up to ``timeout`` s; older queued items count as dropped."""
        with self._cond:
            if not self._cond.wait_for(lambda: len(self._items) > 0 or self._closed, timeout) \
                    or not self._items:
                return None
            item = self._items.pop()
            self.dropped += len(self._items)
            self._items.clear()
            self.taken += 1
            return item

    def drain(self) -> list[T]:
        """All queued items, oldest first (non-blocking)."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            self.taken += len(items)
            return items

    def close(self) -> None:
        """Wake every waiting consumer; later takes return what is left, then None."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed

    def stats(self) -> HandoffStats:
        with self._cond:
            return HandoffStats(self.capacity, self.put_count, self.taken, self.dropped,
                                len(self._items))

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
