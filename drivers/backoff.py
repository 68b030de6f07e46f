"""Exponential back-off between reopen attempts.

Pure: no clock, no sleeping. A driver thread asks :meth:`Backoff.next_delay` for the
time to wait (it waits on its stop event, so ``stop()`` is never delayed) and calls
:meth:`Backoff.reset` once the device works again.
"""

from __future__ import annotations


class Backoff:
    """Delays ``min_s, 2 min_s, 4 min_s, ...`` capped at ``max_s`` (seconds).

    :param min_s: first delay, s (> 0).
    :param max_s: longest delay, s (>= min_s).
    :param factor: growth per attempt (> 1).
    """

    def __init__(self, min_s: float, max_s: float, factor: float = 2.0) -> None:
        if not min_s > 0.0:
            raise ValueError(f"back-off min_s must be > 0, got {min_s}")
        if max_s < min_s:
            raise ValueError(f"back-off max_s ({max_s}) must be >= min_s ({min_s})")
        if not factor > 1.0:
            raise ValueError(f"back-off factor must be > 1, got {factor}")
        self.min_s = float(min_s)
        self.max_s = float(max_s)
        self.factor = float(factor)
        self._next = self.min_s
        self.attempts = 0

    def next_delay(self) -> float:
        """The delay to wait before the next attempt, s; grows for the one after."""
        delay = self._next
        self._next = min(self.max_s, self._next * self.factor)
        self.attempts += 1
        return delay

    def reset(self) -> None:
        """The device works again: the next failure starts from ``min_s``."""
        self._next = self.min_s
        self.attempts = 0
