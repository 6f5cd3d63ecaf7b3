"""User-facing errors: one line, naming the file and the problem.

Library code raises these for bad input; the command line prints ``str(err)`` and exits
non-zero, never a traceback from deep inside a dependency.
"""

from __future__ import annotations

from os import PathLike


class EmogestureError(Exception):
    """Base class of every error meant for the user."""


class InputFileError(EmogestureError, ValueError):
    """A user-given file is missing, unreadable, corrupt, or holds the wrong content."""

    def __init__(self, path: str | PathLike[str], problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class ConfigError(EmogestureError, ValueError):
    """A configuration value or override is invalid."""
