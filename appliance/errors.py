"""Typed errors that the command line turns into one-line messages and exit codes.

``UsageError`` (bad arguments, configuration, recording) exits 2; ``RuntimeFailure``
exits 1. Both carry a message that already names the file, key or line.
"""

from __future__ import annotations

from pathlib import Path


class ApplianceError(Exception):
    """Base of the errors the command line reports without a traceback."""

    exit_code = 1


class UsageError(ApplianceError):
    """Bad arguments, configuration or input files: exit status 2."""

    exit_code = 2


class ConfigError(UsageError):
    """A configuration problem: names the file, the key and what is wrong."""

    def __init__(self, file: str | Path, key: str, problem: str) -> None:
        self.file = str(file)
        self.key = key
        self.problem = problem
        where = f"{self.file}: {key}" if key else self.file
        super().__init__(f"{where}: {problem}")


class RecordingError(UsageError):
    """A bad drive recording: names the file and, where known, the line."""

    def __init__(self, file: str | Path, problem: str, line: int | None = None) -> None:
        self.file = str(file)
        self.line = line
        self.problem = problem
        where = f"{self.file}:{line}" if line is not None else self.file
        super().__init__(f"{where}: {problem}")


class RuntimeFailure(ApplianceError):
    """A failure while running (device gone for good, disk full...): exit status 1."""

    exit_code = 1
