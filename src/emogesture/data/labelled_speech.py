"""Emotion-labelled real speech that a user holds: a manifest of recordings with their emotion, speaker and
split, made from a known corpus layout or written by hand, and the recordings it names joined per speaker and
emotion.

Nothing of the kind ships with the tool or can be had from a package, and the bundled model has heard only
synthetic voices speak with emotion. Real acted emotion is what teaches a perception where a real person's
neutral lies (docs/training.md, 'Emotion-labelled real speech'). A researcher or studio that holds such recordings (CREMA-D, RAVDESS,
their own) can score a model on the speakers it never heard (``evaluate real --labelled MANIFEST``); RAVDESS's
train actors teach the read-out of the front end trained on real speech (``emogesture train bundle
--labelled-root``, :mod:`emogesture.train.heard_readout`).

The manifest is a CSV file with the header ``path,emotion,speaker,split``: ``path`` relative to the
manifest's own folder (or absolute), ``emotion`` one of the seven emotions and neutral (or a common
adjective: happy, angry, sad, fearful, surprised, disgusted, contemptuous), ``speaker`` any name, ``split``
train, val or test. Splits go by speaker: no speaker is in two of them, as BEAT2 splits by actor.

Layouts :func:`scan_layout` knows (the published file names; files of other names are left out):

- ``ravdess``: ``03-01-EE-II-SS-RR-AA.wav``, audio-only speech (modality 03, channel 01); emotions 01
  neutral, 03 happy, 04 sad, 05 angry, 06 fearful, 07 disgust, 08 surprised; 02 calm has no counterpart
  here: heard as neutral (``calm="neutral"``, as RAVDESS's listeners are scored) or left out (``calm="drop"``,
  the default); AA the actor (odd: male, even: female).
- ``crema-d``: ``AAAA_SSS_EEE_LL.wav``, AAAA the actor; EEE one of ANG DIS FEA HAP NEU SAD.
- ``folders``: ``SPEAKER/EMOTION/*.wav`` (or .flac, .ogg, .mp3): one's own recordings.
"""

from __future__ import annotations

import csv
import io
import re
from collections import defaultdict
from dataclasses import dataclass, replace
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE as SAMPLE_RATE, load_audio
from emogesture.data.beat import EMOTIONS
from emogesture.data.real_speech import join_clips
from emogesture.errors import EmogestureError, InputFileError

SPLITS = ("train", "val", "test")
HEADER = ("path", "emotion", "speaker", "split")
LAYOUTS = ("ravdess", "crema-d", "folders")
CALM = ("drop", "neutral")  # what RAVDESS's calm clips are
AUDIO_SUFFIXES = (".wav", ".flac", ".ogg", ".mp3")
#: Emotion words of labelled corpora -> the emotions here.
EMOTION_WORDS = {e: e for e in EMOTIONS} | {
    "happy": "happiness", "joy": "happiness", "angry": "anger", "sad": "sadness", "fearful": "fear",
    "afraid": "fear", "surprised": "surprise", "disgusted": "disgust", "contemptuous": "contempt"}
_RAVDESS = re.compile(r"^03-01-(\d\d)-\d\d-\d\d-\d\d-(\d\d)$")
_RAVDESS_EMOTIONS = {"01": "neutral", "03": "happiness", "04": "sadness", "05": "anger", "06": "fear",
                     "07": "disgust", "08": "surprise"}
_CREMA = re.compile(r"^(\d{4})_[A-Z]{3}_([A-Z]{3})_[A-Z0-9]{2}$")
_CREMA_EMOTIONS = {"ANG": "anger", "DIS": "disgust", "FEA": "fear", "HAP": "happiness", "NEU": "neutral",
                   "SAD": "sadness"}


@dataclass(frozen=True)
class LabelledClip:
    """One recording: its file, the emotion it is spoken with, its speaker and its split."""

    path: Path
    emotion: str
    speaker: str
    split: str = "train"


def emotion_name(word: str) -> str | None:
    """A corpus's emotion word (any case) -> one of ``EMOTIONS``, or None."""
    return EMOTION_WORDS.get(word.strip().lower())


def scan_layout(layout: str, root: str | PathLike[str], calm: str = "drop") -> list[LabelledClip]:
    """The labelled recordings under ``root`` in a known ``layout`` (module docstring), every one in the train
    split, sorted by path; ``calm``: RAVDESS's calm clips heard as ``neutral`` or left out (``drop``). Raises a one-line
    error for an unknown layout or when none is found."""
    root = Path(root)
    if layout not in LAYOUTS:
        raise EmogestureError(f"layout {layout!r}: unknown; known: {', '.join(LAYOUTS)}")
    if calm not in CALM:
        raise EmogestureError(f"calm {calm!r}: one of {', '.join(CALM)}")
    ravdess = _RAVDESS_EMOTIONS | ({"02": "neutral"} if calm == "neutral" else {})
    if not root.is_dir():
        raise InputFileError(root, "not a folder")
    clips = []
    for path in sorted(p for p in root.rglob("*") if p.suffix.lower() in AUDIO_SUFFIXES and p.is_file()):
        if layout == "ravdess":
            m = _RAVDESS.match(path.stem)
            if m and m.group(1) in ravdess:
                clips.append(LabelledClip(path, ravdess[m.group(1)], f"actor{m.group(2)}"))
        elif layout == "crema-d":
            m = _CREMA.match(path.stem)
            if m and m.group(2) in _CREMA_EMOTIONS:
                clips.append(LabelledClip(path, _CREMA_EMOTIONS[m.group(2)], m.group(1)))
        else:
            parts = path.relative_to(root).parts
            emotion = emotion_name(parts[-2]) if len(parts) == 3 else None
            if emotion is not None:
                clips.append(LabelledClip(path, emotion, parts[0]))
    if not clips:
        raise InputFileError(root, f"no recordings named as the {layout} layout names them")
    return clips


def assign_speaker_splits(clips: list[LabelledClip], val_speakers: int | list[str], test_speakers: int | list[str],
                          seed: int = 0) -> list[LabelledClip]:
    """``clips`` with their split set by speaker: ``test_speakers`` to test and ``val_speakers`` to val, each
    a list of speaker names or a count of speakers drawn from ``default_rng(seed)``; the rest to train."""
    speakers = sorted({c.speaker for c in clips})
    named = [s for group in (val_speakers, test_speakers) if isinstance(group, list) for s in group]
    if unknown := [s for s in named if s not in speakers]:
        raise EmogestureError(f"speaker {unknown[0]!r}: none of the recordings is theirs; speakers: {', '.join(speakers)}")
    if len(set(named)) != len(named):
        raise EmogestureError("a speaker is named for both val and test (or twice)")
    counts = [len(g) if isinstance(g, list) else g for g in (val_speakers, test_speakers)]
    if min(counts) < 0 or sum(counts) >= len(speakers):
        raise EmogestureError(f"{len(speakers)} speakers cannot give {counts[0]} val and {counts[1]} test "
                              "speakers and keep one to train on")
    free = [s for s in speakers if s not in named]
    order = [free[i] for i in np.random.default_rng(seed).permutation(len(free))]
    split = {}
    for name, group in (("test", test_speakers), ("val", val_speakers)):
        chosen = group if isinstance(group, list) else [order.pop(0) for _ in range(group)]
        split |= {s: name for s in chosen}
    return [replace(c, split=split.get(c.speaker, "train")) for c in clips]


def manifest_text(clips: list[LabelledClip], folder: str | PathLike[str]) -> str:
    """The manifest of ``clips`` (paths relative to ``folder``, the manifest's folder, where they lie
    under it) as CSV text."""
    folder = Path(folder).resolve()
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(HEADER)
    for c in clips:
        path = Path(c.path).resolve()
        writer.writerow([path.relative_to(folder) if path.is_relative_to(folder) else path, c.emotion, c.speaker,
                         c.split])
    return out.getvalue()


def read_manifest(path: str | PathLike[str]) -> list[LabelledClip]:
    """The clips of a labelled-speech manifest (module docstring); paths resolved against its folder. Raises a
    one-line error naming the file (and line) for a missing file, a wrong header, an unknown emotion or
    split, a missing recording, or a speaker in two splits."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "labelled-speech manifest not found")
    rows = list(csv.reader(path.read_text(encoding="utf-8").splitlines()))
    if not rows or tuple(h.strip() for h in rows[0]) != HEADER:
        raise InputFileError(path, f"not a labelled-speech manifest: its first line must be {','.join(HEADER)}")
    clips, splits = [], defaultdict(set)
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != len(HEADER):
            raise InputFileError(path, f"line {line}: {len(row)} fields, expected {len(HEADER)}")
        file, word, speaker, split = (r.strip() for r in row)
        emotion = emotion_name(word)
        if emotion is None:
            raise InputFileError(path, f"line {line}: emotion {word!r} unknown; known: {', '.join(EMOTIONS)}")
        if split not in SPLITS:
            raise InputFileError(path, f"line {line}: split {split!r}; one of {', '.join(SPLITS)}")
        clip = Path(file) if Path(file).is_absolute() else path.parent / file
        if not clip.is_file():
            raise InputFileError(path, f"line {line}: recording {clip} not found")
        clips.append(LabelledClip(clip, emotion, speaker, split))
        splits[speaker].add(split)
    mixed = sorted(s for s, where in splits.items() if len(where) > 1)
    if mixed:
        raise InputFileError(path, f"speaker {mixed[0]} is in more than one split; splits go by speaker")
    if not clips:
        raise InputFileError(path, "names no recording")
    return clips


def labelled_recordings(clips: list[LabelledClip], split: str,
                        min_seconds: float = 0.0) -> dict[str, tuple[np.ndarray, str]]:
    """The ``split``'s clips joined per speaker and emotion, in path order with 0.3 s of silence between them
    and repeated until at least ``min_seconds`` long (:func:`~emogesture.data.real_speech.join_clips`):
    ``"SPEAKER_EMOTION"`` -> (16-kHz waveform ``[N]`` float32, emotion), sorted by name."""
    if split not in SPLITS:
        raise EmogestureError(f"split {split!r}; one of {', '.join(SPLITS)}")
    groups: dict[tuple[str, str], list[Path]] = defaultdict(list)
    for c in clips:
        if c.split == split:
            groups[(c.speaker, c.emotion)].append(Path(c.path))
    if not groups:
        raise EmogestureError(f"the labelled speech holds no recording of the {split} split")
    return {f"{speaker}_{emotion}": (join_clips([load_audio(p, target_sr=SAMPLE_RATE)[0] for p in sorted(paths)],
                                                min_seconds), emotion)
            for (speaker, emotion), paths in sorted(groups.items())}
