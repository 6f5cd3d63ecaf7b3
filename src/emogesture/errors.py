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


class OutputExistsError(EmogestureError, FileExistsError):
    """An output file already exists and overwriting was not asked for."""

    def __init__(self, path: str | PathLike[str]) -> None:
        self.path = str(path)
        super().__init__(f"{self.path}: already exists (pass --overwrite to replace it)")

    def __str__(self) -> str:
        return str(self.args[0])
