"""BEAT / BEAT2 conventions: take names, speakers, emotions, splits, semantic scores, TextGrids.

Take names look like ``<spk>_<name>_<type>_<start>_<end>`` (e.g. ``2_scott_0_103_103``). Type 0 is
English speech, 1 English conversation; the take id (``start``) of a speech take gives its emotion
(docs/design.md, 'Data'). Conversations are neutral.
"""

from __future__ import annotations

import csv
import re
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.errors import InputFileError
from emogesture.types import EMOTIONS  # noqa: F401  (the emotions' home is types; read here by the data code)

# Inclusive take-id ranges of each emotion for speech takes (type 0), in EMOTIONS order.
EMOTION_TAKE_RANGES: tuple[tuple[int, int], ...] = (
    (1, 64), (65, 72), (73, 80), (81, 86), (87, 94), (95, 102), (103, 110), (111, 118),
)
SPEAKERS: dict[int, str] = {
    1: "wayne", 2: "scott", 3: "solomon", 4: "lawrence", 5: "stewart", 6: "carla", 7: "sophie",
    8: "catherine", 9: "miranda", 10: "kieks", 11: "nidal", 12: "zhao", 13: "lu", 14: "zhang",
    15: "carlos", 16: "jorge", 17: "itoi", 18: "daiki", 19: "jaime", 20: "li", 21: "ayana",
    22: "luqi", 23: "hailing", 24: "kexin", 25: "goto", 26: "reamey", 27: "yingqing",
    28: "tiffnay", 29: "hanieh", 30: "katya",
}
TAKE_TYPES: dict[int, str] = {0: "english_speech", 1: "english_conversation"}
# The authors' actor split (docs/design.md, 'Data').
ACTOR_SPLIT: dict[str, tuple[str, ...]] = {
    "val": ("nidal", "zhang", "carlos", "itoi", "jaime", "li"),
    "test": ("luqi", "hailing", "kexin", "goto", "tiffnay", "hanieh"),
}
SPLITS = ("train", "val", "test", "additional")

_TAKE_RE = re.compile(r"^(\d+)_([a-z]+)_(\d+)_(\d+)_(\d+)$")


def emotion_of_take_id(take_id: int) -> int:
    """Emotion label index (into EMOTIONS) of a speech take id 1–118."""
    for label, (lo, hi) in enumerate(EMOTION_TAKE_RANGES):
        if lo <= take_id <= hi:
            return label
    raise ValueError(f"take id {take_id} is outside the speech range 1-118")


@dataclass(frozen=True)
class TakeInfo:
    """What a BEAT take name says."""

    name: str
    speaker_id: int
    speaker: str
    take_type: int
    take: int
    end: int
    emotion: int  # index into EMOTIONS

    @property
    def emotion_name(self) -> str:
        return EMOTIONS[self.emotion]

    @property
    def is_speech(self) -> bool:
        return self.take_type == 0


def parse_take_name(name: str) -> TakeInfo:
    """Parse ``"2_scott_0_103_103"`` (a bare stem or a file name/path).

    Raises:
        ValueError: the name does not follow ``<spk>_<name>_<type>_<start>_<end>``, or a speech
            take id lies outside 1–118.
    """
    stem = Path(str(name)).name
    for suffix in (".npz", ".wav", ".TextGrid", ".txt", ".bvh", ".json"):
        if stem.endswith(suffix):
            stem = stem[: -len(suffix)]
            break
    m = _TAKE_RE.match(stem)
    if not m:
        raise ValueError(
            f"{name!r} is not a BEAT take name (expected <speaker>_<name>_<type>_<start>_<end>, "
            "e.g. 2_scott_0_103_103)"
        )
    spk, spk_name, ttype, start, end = m.groups()
    take_type, take = int(ttype), int(start)
    emotion = emotion_of_take_id(take) if take_type == 0 else 0
    return TakeInfo(stem, int(spk), spk_name, take_type, take, int(end), emotion)


def format_take_name(speaker_id: int, take: int, take_type: int = 0, speaker: str | None = None) -> str:
    """The BEAT name of a take, e.g. ``format_take_name(2, 103) == "2_scott_0_103_103"``."""
    name = speaker if speaker is not None else SPEAKERS[speaker_id]
    return f"{speaker_id}_{name}_{take_type}_{take}_{take}"


def read_split_csv(path: str | PathLike[str]) -> dict[str, str]:
    """Read ``train_test_split.csv`` (header ``id,type``) into ``{take: split}``."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "split file not found")
    out: dict[str, str] = {}
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        if reader.fieldnames is None or not {"id", "type"} <= set(reader.fieldnames):
            raise InputFileError(path, f"expected a header 'id,type', got {reader.fieldnames}")
        for row in reader:
            split = row["type"].strip()
            if split not in SPLITS:
                raise InputFileError(path, f"unknown split {split!r} for take {row['id']!r}")
            out[row["id"].strip()] = split
    return out


def write_split_csv(path: str | PathLike[str], splits: dict[str, str]) -> None:
    """Write ``{take: split}`` as ``id,type`` rows, sorted by take name."""
    with Path(path).open("w", newline="") as f:
        f.write("id,type\n")
        for take in sorted(splits):
            f.write(f"{take},{splits[take]}\n")


def actor_split(take: str | TakeInfo) -> str:
    """The authors' split by actor: val/test speakers as in docs/design.md, 'Data'; everyone else train."""
    info = take if isinstance(take, TakeInfo) else parse_take_name(take)
    for split, speakers in ACTOR_SPLIT.items():
        if info.speaker in speakers:
            return split
    return "train"


@dataclass(frozen=True)
class SemSegment:
    """One row of a BEAT ``sem`` file."""

    kind: str
    start: float
    end: float
    score: float
    keywords: str


def read_sem(path: str | PathLike[str]) -> list[SemSegment]:
    """Read a tab-separated ``sem/*.txt`` file: type, start s, end s, duration s, score, keywords."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "semantic annotation file not found")
    segments = []
    for lineno, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
        if not line.strip():
            continue
        cols = line.split("\t")
        try:
            kind, start, end, score = cols[0], float(cols[1]), float(cols[2]), float(cols[4])
        except (IndexError, ValueError):
            raise InputFileError(path, f"line {lineno} is not 'type, start, end, duration, score, keywords'")
        keywords = cols[5].strip() if len(cols) > 5 else ""
        segments.append(SemSegment(kind.strip(), start, end, score, keywords))
    return segments


def sem_frame_scores(segments: Iterable[SemSegment], num_frames: int, fps: float = 30.0) -> np.ndarray:
    """Per-frame semantic score: the score of the segment covering the frame's time, else 0.

    A frame at time ``i / fps`` is covered by ``[start, end)``. Where segments overlap, the
    highest score wins.
    """
    scores = np.zeros(num_frames, np.float32)
    times = np.arange(num_frames) / fps
    for seg in segments:
        covered = (times >= seg.start) & (times < seg.end)
        scores[covered] = np.maximum(scores[covered], seg.score)
    return scores


def read_textgrid_words(path: str | PathLike[str]) -> list[tuple[float, float, str]]:
    """Words ``(start s, end s, word)`` of the first interval tier of a Praat TextGrid (long format).

    Empty intervals (pauses) are skipped.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "TextGrid file not found")
    text = path.read_text(encoding="utf-8", errors="replace")
    tiers = re.split(r"item\s*\[\d+\]:", text)[1:]
    if not tiers:
        raise InputFileError(path, "no tiers found (not a long-format TextGrid)")
    words = []
    pattern = re.compile(r'xmin\s*=\s*([\d.eE+-]+)\s*xmax\s*=\s*([\d.eE+-]+)\s*text\s*=\s*"([^"]*)"')
    for xmin, xmax, word in pattern.findall(tiers[0]):
        if word.strip():
            words.append((float(xmin), float(xmax), word.strip()))
    return words


def group_takes_by_text(takes: Sequence[str | TakeInfo]) -> dict[tuple[int, int], list[TakeInfo]]:
    """Group takes that share a text: same take type and take id, different speakers.

    In BEAT every speaker records the same numbered texts, so ``(type, take)`` identifies the text.
    Returns ``{(type, take): [TakeInfo, ...]}`` with at least one take per group, speakers sorted.
    """
    groups: dict[tuple[int, int], list[TakeInfo]] = defaultdict(list)
    for t in takes:
        info = t if isinstance(t, TakeInfo) else parse_take_name(t)
        groups[(info.take_type, info.take)].append(info)
    return {k: sorted(v, key=lambda i: i.speaker_id) for k, v in sorted(groups.items())}
