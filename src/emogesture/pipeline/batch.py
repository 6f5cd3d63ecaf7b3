"""Many recordings at once: what ``emogesture generate A.wav B.flac folder/`` does, callable from Python.

The models are loaded once (one :class:`~emogesture.pipeline.generate.GesturePipeline`); each recording is
one :class:`~emogesture.pipeline.animate.AnimationRequest` made from a template. A recording that fails
(unreadable, silent, outputs in the way) is reported with its one-line error and the others go on. With
``skip_existing`` a batch that was interrupted resumes: a recording whose outputs all exist is skipped, one
with some missing writes only those (outputs are written whole or not at all, and generation is
reproducible, so a resumed batch leaves the files an uninterrupted one would have).

Example (the bundled model; every recording of ``talks/`` as npz and bvh into ``out/``)::

    pipe = GesturePipeline.from_run()
    items = animate_files(pipe, speech_files(["talks/"]), AnimationRequest("", "out", formats="npz,bvh"))
    failed = [item for item in items if item.error]
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from os import PathLike
from pathlib import Path

from tqdm import tqdm

from emogesture.errors import EmogestureError, InputFileError
from emogesture.pipeline.animate import AnimationRequest, AnimationResult, animate
from emogesture.pipeline.generate import GesturePipeline
from emogesture.types import SMPLXSequence

__all__ = ["AUDIO_SUFFIXES", "BatchItem", "animate_files", "batch_summary", "speech_files"]

#: What a folder given as input contributes: its files with these suffixes (any case), sorted by name.
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".oga", ".opus", ".mp3", ".m4a", ".aac", ".aiff", ".aif")


def speech_files(paths: Sequence[str | PathLike[str]]) -> list[Path]:
    """Files and folders -> the recordings to animate, in the order given (a folder's audio files sorted by
    name, not its subfolders; a file given twice once). A missing path, or a folder without audio, is a
    one-line error."""
    out: list[Path] = []
    for item in map(Path, paths):
        if item.is_dir():
            found = sorted(p for p in item.iterdir() if p.is_file() and p.suffix.lower() in AUDIO_SUFFIXES)
            if not found:
                raise InputFileError(item, f"holds no audio files ({', '.join(AUDIO_SUFFIXES)})")
            out += found
        elif item.exists():
            out.append(item)
        else:
            raise InputFileError(item, "not found")
    seen: set[Path] = set()
    unique = []
    for p in out:
        if p.resolve() not in seen:
            seen.add(p.resolve())
            unique.append(p)
    return unique


@dataclass
class BatchItem:
    """One recording of a batch: what it wrote (None when it failed) or its one-line error."""

    speech: Path
    result: AnimationResult | None = None
    error: str | None = None

    @property
    def skipped(self) -> bool:
        return self.result is not None and self.result.skipped


def _same_outputs(requests: list[AnimationRequest]) -> None:
    """Refuse a batch where two recordings would write the same file (the same name in two folders)."""
    owner: dict[Path, Path] = {}
    for request in requests:
        for path in request.outputs():
            if path in owner:
                raise EmogestureError(f"{owner[path]} and {request.speech} would both write {path.name}; "
                                      "give them different names or animate them into different --out folders")
            owner[path] = request.speech


def animate_files(pipe: GesturePipeline, speeches: Sequence[str | PathLike[str]], template: AnimationRequest, *,
                  progress: bool = False, report: Callable[[str], None] | None = None,
                  written: Callable[[Path, SMPLXSequence], None] | None = None,
                  finished: Callable[["BatchItem"], None] | None = None, verbose: bool = False) -> list[BatchItem]:
    """Animate every recording of ``speeches`` with the settings of ``template`` (its ``speech`` is
    replaced by each). ``progress``: one bar over the recordings (each recording's own bars when there is
    one); ``report`` and ``written`` as in :func:`~emogesture.pipeline.animate.animate`; ``finished(item)``
    as each recording is done, animated, skipped or failed. Returns one :class:`BatchItem` per recording, in order."""
    requests = [replace(template, speech=Path(s)) for s in speeches]
    _same_outputs(requests)
    items = []
    single = len(requests) == 1
    with tqdm(total=len(requests), desc="animating", unit="file", disable=not progress or single) as bar:
        for request in requests:
            item = BatchItem(request.speech)
            try:
                item.result = animate(pipe, request, progress=progress and single, report=report, written=written,
                                      verbose=verbose)
            except EmogestureError as e:
                item.error = str(e) if str(request.speech) in str(e) else f"{request.speech}: {e}"
            except (OSError, ValueError, RuntimeError) as e:  # not ours: still one line, and the batch goes on
                first = str(e).splitlines()[0] if str(e) else ""
                item.error = f"{request.speech}: {type(e).__name__}{': ' + first if first else ''}"
            if finished is not None:
                finished(item)
            items.append(item)
            bar.update()
    return items


def batch_summary(items: Sequence[BatchItem]) -> str:
    """One line: how many recordings were animated, skipped (already done) and failed."""
    failed = sum(item.error is not None for item in items)
    skipped = sum(item.skipped for item in items)
    done = len(items) - failed - skipped
    return (f"{done} of {len(items)} recording{'s' * (len(items) != 1)} animated"
            + (f", {skipped} already done (skipped)" if skipped else "") + (f", {failed} failed" if failed else ""))
