"""The link state every driver reports, held thread-safely so callers can wait on it."""

from __future__ import annotations

import enum
import logging
import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar


class LinkState(enum.Enum):
    """What a driver reports about its device.

    ``STARTING``: not opened yet; ``OK``: delivering fresh data; ``STALE``: open but the
    data is older than the driver's staleness limit (or the device stopped answering);
    ``LOST``: the device or interface is gone and is being reopened with back-off;
    ``STOPPED``: ``stop()``/``close()`` was called.
    """

    STARTING = "starting"
    OK = "ok"
    STALE = "stale"
    LOST = "lost"
    STOPPED = "stopped"


class LinkStatus:
    """Current :class:`LinkState` of one driver, with a wait for changes.

    Transitions are logged once (warning when leaving ``OK``, info when reaching it),
    so a reconnecting device is loud in the journal but a steady one is silent.
    """

    def __init__(self, name: str, logger: logging.Logger) -> None:
        self._name = name
        self._log = logger
        self._state = LinkState.STARTING
        self._why = ""
        self._cond = threading.Condition()

    @property
    def state(self) -> LinkState:
        return self._state

    @property
    def reason(self) -> str:
        """Why the state was last changed (empty for a normal transition)."""
        return self._why

    def set(self, state: LinkState, why: str = "") -> None:
        with self._cond:
            if state is self._state:
                return
            old, self._state, self._why = self._state, state, why
            self._cond.notify_all()
        suffix = f": {why}" if why else ""
        if state is LinkState.OK:
            self._log.info("%s: %s -> ok%s", self._name, old.value, suffix)
        elif state is not LinkState.STOPPED:
            self._log.warning("%s: %s -> %s%s", self._name, old.value, state.value, suffix)

    def wait_for(self, state: LinkState, timeout: float) -> bool:
        """Block until the state is ``state`` or ``timeout`` (s) passes; True if reached."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._state is not state:
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return False
                self._cond.wait(remaining)
            return True


class Counters:
    """Named event counters of one driver (thread-safe), with the latest error text.

    Drivers expose them as a frozen ``stats`` snapshot; :meth:`wait_for` lets a caller
    (or a test) block until the counters satisfy a condition, without polling.
    """

    def __init__(self) -> None:
        self._counts: dict[str, Any] = {}
        self._last_error = ""
        self._cond = threading.Condition()

    def add(self, name: str, n: int = 1, error: str = "") -> None:
        with self._cond:
            self._counts[name] = self._counts.get(name, 0) + n
            if error:
                self._last_error = error
            self._cond.notify_all()

    def snapshot(self) -> tuple[dict[str, Any], str]:
        """(counts, last error text)."""
        with self._cond:
            return dict(self._counts), self._last_error

    def wait_for(self, predicate: Callable[[dict[str, Any]], bool], timeout: float) -> bool:
        """Block until ``predicate(counts)`` holds (missing names read as absent) or timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate(self._counts):
                remaining = deadline - time.monotonic()
                if remaining <= 0.0:
                    return False
                self._cond.wait(remaining)
            return True


S = TypeVar("S")


class Reporting(Generic[S]):
    """What every driver reports, in one place: its link state and its counters, both waitable.

    A driver sets ``_status`` (:class:`LinkStatus`), ``_counts`` (:class:`Counters`) and the
    frozen dataclass its ``stats`` snapshot is made of (``_stats_type``, with a
    ``last_error`` field).
    """

    _status: LinkStatus
    _counts: Counters
    _stats_type: Callable[..., S]

    @property
    def state(self) -> LinkState:
        return self._status.state

    def wait_state(self, state: LinkState, timeout: float) -> bool:
        """Block until the driver reaches ``state`` (or ``timeout`` s); True if it did."""
        return self._status.wait_for(state, timeout)

    @property
    def stats(self) -> S:
        counts, last_error = self._counts.snapshot()
        return self._stats_type(**counts, last_error=last_error)

    def wait_stats(self, predicate: Callable[[S], bool], timeout: float) -> bool:
        """Block until ``predicate(stats)`` holds or ``timeout`` s pass; True if it did."""
        return self._counts.wait_for(lambda c: predicate(self._stats_type(**c)), timeout)
