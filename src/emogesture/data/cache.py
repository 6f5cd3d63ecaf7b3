"""Reading a prepared windows cache (written by :mod:`emogesture.data.prepare`).

A cache directory holds, per split, memory-mappable arrays of aligned 10-s windows:

- ``<split>/fbank.npy``  ``[W, 1024, n_mels]`` float16, normalised with the cache's fbank statistics;
- ``<split>/motion.npy`` ``[W, 300, D]`` float32 raw motion features (6D rotations: docs/design.md,
  'Motion representation');
- ``<split>/sem.npy``    ``[W, 300]`` float32 per-frame semantic scores (0 where unknown);
- ``<split>/windows.csv`` one row per window: take, speaker_id, emotion, text, start_s.

plus ``stats.json`` (fbank mean/std, motion feature mean/std) and ``manifest.json`` (config, counts,
version), which is written last and marks the cache complete.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import csv
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.errors import InputFileError
from emogesture.fileio import read_json

CACHE_VERSION = 1
WINDOW_COLUMNS = ("take", "speaker_id", "emotion", "text", "start_s")


@dataclass
class SplitWindows:
    """One split of a windows cache; arrays are read-only memory maps."""

    fbank: np.ndarray  # [W, 1024, n_mels] float16
    motion: np.ndarray  # [W, 300, D] float32
    sem: np.ndarray  # [W, 300] float32
    takes: list[str]
    speaker_id: np.ndarray  # [W] int64
    emotion: np.ndarray  # [W] int64
    text: np.ndarray  # [W] int64, text group (same text spoken by several speakers)
    start_s: np.ndarray  # [W] float64

    def __len__(self) -> int:
        return int(self.fbank.shape[0])

    def take_emotions(self, leave_out_speakers: Iterable[int] = ()) -> dict[str, int]:
        """Each take of the split, in order, and its emotion index; without the takes of the speakers
        ``leave_out_speakers`` (a model's training voices: what is left are the voices it never heard)."""
        heard = {int(s) for s in leave_out_speakers}
        return {t: int(e) for t, s, e in zip(self.takes, self.speaker_id.tolist(), self.emotion.tolist())
                if s not in heard}


@dataclass
class WindowsCache:
    """A complete prepared cache: manifest, statistics, and the splits present."""

    root: Path
    manifest: dict
    stats: dict

    @property
    def splits(self) -> list[str]:
        return [s for s, n in self.manifest["windows"].items() if n > 0]

    def split(self, name: str) -> SplitWindows:
        """Memory-map the arrays of one split (``train``, ``val``, ``test``)."""
        if self.manifest["windows"].get(name, 0) == 0:
            raise InputFileError(self.root, f"the cache has no windows in split {name!r} (has {self.splits})")
        d = self.root / name
        takes, spk, emo, text, start = [], [], [], [], []
        with (d / "windows.csv").open(newline="") as f:
            for row in csv.DictReader(f):
                takes.append(row["take"])
                spk.append(int(row["speaker_id"]))
                emo.append(int(row["emotion"]))
                text.append(int(row["text"]))
                start.append(float(row["start_s"]))
        return SplitWindows(
            fbank=np.load(d / "fbank.npy", mmap_mode="r"),
            motion=np.load(d / "motion.npy", mmap_mode="r"),
            sem=np.load(d / "sem.npy", mmap_mode="r"),
            takes=takes,
            speaker_id=np.asarray(spk, np.int64),
            emotion=np.asarray(emo, np.int64),
            text=np.asarray(text, np.int64),
            start_s=np.asarray(start, np.float64),
        )


def concat_splits(cache: WindowsCache, names: Sequence[str]) -> SplitWindows:
    """Several splits as one (arrays loaded into memory; a single split stays memory-mapped)."""
    parts = [cache.split(n) for n in names]
    if len(parts) == 1:
        return parts[0]
    return SplitWindows(
        **{k: np.concatenate([getattr(p, k) for p in parts]) for k in
           ("fbank", "motion", "sem", "speaker_id", "emotion", "text", "start_s")},
        takes=[t for p in parts for t in p.takes],
    )


def open_cache(root: str | PathLike[str]) -> WindowsCache:
    """Open a cache written by ``emogesture prepare``; a missing or incomplete cache is an error."""
    root = Path(root)
    manifest_path = root / "manifest.json"
    if not manifest_path.is_file():
        raise InputFileError(root, "not a complete windows cache (no manifest.json); run `emogesture prepare` first")
    manifest = read_json(manifest_path, "cache manifest")
    stats = read_json(root / "stats.json", "cache statistics")
    if manifest.get("cache_version") != CACHE_VERSION:
        raise InputFileError(
            root, f"cache version {manifest.get('cache_version')} is not {CACHE_VERSION}; re-run `emogesture prepare`"
        )
    return WindowsCache(root, manifest, stats)
