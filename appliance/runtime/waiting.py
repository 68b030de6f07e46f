""""Still waiting" lines while a device stays missing.

The drivers log a device that goes missing once, when it happens, and then retry quietly
with back-off. An engineer watching ``journalctl -f`` during installation would otherwise
see nothing more and cannot tell a retrying appliance from a hung one, so while a device
stays lost or silent the processing thread reports it again every ``every_s`` seconds, with
the driver's latest error. Pure: time is an argument.
"""

from __future__ import annotations

from dataclasses import dataclass, field

EVERY_S = 10.0  # s between two lines about the same missing device


@dataclass
class StillWaiting:
    """Per device name: since when it is missing and when it was last reported."""

    every_s: float = EVERY_S
    _since: dict[str, float] = field(default_factory=dict)
    _reported: dict[str, float] = field(default_factory=dict)

    def update(self, now: float, name: str, missing: bool, why: str = "") -> str | None:
        """A line to log when ``name`` has been missing for another ``every_s`` s, else None."""
        if not missing:
            self._since.pop(name, None)
            self._reported.pop(name, None)
            return None
        since = self._since.setdefault(name, now)
        last = self._reported.get(name, since)
        if now - last < self.every_s:
            return None
        self._reported[name] = now
        reason = f" ({why})" if why else ""
        return f"{name}: still waiting after {now - since:.0f} s{reason}; retrying"
