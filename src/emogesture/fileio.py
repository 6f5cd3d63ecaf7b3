"""Writing user-visible files whole or not at all: a temporary file beside the target, fsync, rename."""

from __future__ import annotations

import os
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from os import PathLike
from pathlib import Path

from emogesture.errors import EmogestureError, InputFileError, OutputExistsError


def check_output(path: str | PathLike[str], overwrite: bool = False) -> Path:
    """Refuse an output ``path`` that exists (unless ``overwrite``) or is a folder; returns it as a Path."""
    path = Path(path)
    if path.is_dir():
        raise EmogestureError(f"{path}: is a folder, not a file name for the output")
    if path.exists() and not overwrite:
        raise OutputExistsError(path)
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise EmogestureError(f"{path}: cannot write there, {parent} is a file, not a folder")
            break
    return path


def fsync_dir(folder: str | PathLike[str]) -> None:
    """Flush a folder's entries (a rename in it) to disk; a no-op where folders cannot be opened."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextmanager
def atomic_output(path: str | PathLike[str], overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; when the block ends without error, the file written
    there is flushed to disk and renamed to ``path`` (so readers never see a partial file). On error
    the temporary file is removed and ``path`` is left as it was.

    Raises:
        OutputExistsError: ``path`` exists and ``overwrite`` is False (checked before and after).
        EmogestureError: the folder cannot be made or the file cannot be written (one line).
    """
    path = check_output(path, overwrite)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise EmogestureError(f"{path}: cannot create its folder ({err.strerror or err})") from None
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # its mode honours the umask
        yield tmp
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        if path.exists() and not overwrite:  # appeared while we were writing
            raise OutputExistsError(path)
        os.replace(tmp, path)
        fsync_dir(path.parent)
    except OSError as err:
        if isinstance(err, OutputExistsError):
            raise
        raise EmogestureError(f"{path}: cannot write ({err.strerror or err})") from None
    finally:
        tmp.unlink(missing_ok=True)


def read_json(path: str | PathLike[str], what: str = "JSON file") -> dict:
    """A JSON object from ``path``; a missing, unreadable, corrupt or non-object file is one
    :class:`InputFileError` naming the file (``what`` says what it should have been)."""
    import json

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputFileError(path, f"{what} not found") from None
    except UnicodeDecodeError:
        raise InputFileError(path, f"not a readable {what} (not UTF-8 text)") from None
    except OSError as err:
        raise InputFileError(path, f"cannot read the {what} ({err.strerror or err})") from None
    try:
        blob = json.loads(text)
    except ValueError as err:
        raise InputFileError(path, f"corrupt {what}: not valid JSON ({err})") from None
    if not isinstance(blob, dict):
        raise InputFileError(path, f"corrupt {what}: expected a JSON object")
    return blob
