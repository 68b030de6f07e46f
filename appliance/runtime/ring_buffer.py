"""The runtime's ring buffers: one per sensor stream, between a driver thread and processing.

Fixed capacity, overwrite-oldest, never blocking the producer, with counters for
what was dropped. The implementation is the drivers' hand-off buffer (a driver
can push into it directly as its ``sink``); this module gives it the runtime's name.
"""

from drivers.handoff import Handoff as RingBuffer
from drivers.handoff import HandoffStats as RingStats

__all__ = ["RingBuffer", "RingStats"]
