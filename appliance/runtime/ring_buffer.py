"""Fixed-capacity, overwrite-oldest ring buffer between a driver thread and the processing thread.

A producer (driver) never blocks: when the buffer is full the oldest item is
overwritten and counted as dropped. The consumer takes either everything
(``drain``, for sensor samples) or only the newest item (``take_newest``, for
frames: the processing thread works on the newest frame it can keep up with and
the older ones count as dropped).
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass
from typing import Generic, TypeVar

T = TypeVar("T")


@dataclass(frozen=True)
class RingStats:
    """Counters of a ring buffer: items pushed, taken, and dropped (overwritten or skipped)."""

    capacity: int
    pushed: int
    taken: int
    dropped: int
    size: int


class RingBuffer(Generic[T]):
    """Thread-safe ring buffer of fixed ``capacity``.

    :param capacity: number of items kept; the oldest is overwritten beyond it.
    """

    def __init__(self, capacity: int) -> None:
        if capacity < 1:
            raise ValueError("capacity must be at least 1")
        self.capacity = capacity
        self._items: deque[T] = deque()
        self._cond = threading.Condition()
        self._pushed = 0
        self._taken = 0
        self._dropped = 0
        self._closed = False

    def push(self, item: T) -> None:
        """Add ``item``; overwrites (and counts) the oldest when full. Never blocks."""
        with self._cond:
            if len(self._items) >= self.capacity:
                self._items.popleft()
                self._dropped += 1
            self._items.append(item)
            self._pushed += 1
            self._cond.notify_all()

    def drain(self) -> list[T]:
        """Remove and return every item, oldest first."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            self._taken += len(items)
            return items

    def take_newest(self, timeout: float | None = None) -> T | None:
        """Wait up to ``timeout`` s for an item; return the newest, dropping (and counting) older ones.

        Returns None on timeout or when the buffer was closed and is empty.
        """
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait_for(lambda: bool(self._items) or self._closed, timeout)
            if not self._items:
                return None
            item = self._items.pop()
            self._dropped += len(self._items)
            self._items.clear()
            self._taken += 1
            return item

    def take_oldest(self, timeout: float | None = None) -> T | None:
        """Wait up to ``timeout`` s for an item and return the oldest (no dropping)."""
        with self._cond:
            if not self._items and not self._closed:
                self._cond.wait_for(lambda: bool(self._items) or self._closed, timeout)
            if not self._items:
                return None
            self._taken += 1
            return self._items.popleft()

    def close(self) -> None:
        """Wake every waiting consumer; later takes return what is left, then None."""
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        return self._closed

    def stats(self) -> RingStats:
        with self._cond:
            return RingStats(self.capacity, self._pushed, self._taken, self._dropped, len(self._items))
