"""Real recorded speech for checks (never for training): what a user gives the tool.

No emotion-labelled real speech can be had here, but real recordings can: Debian's
``pocketsphinx-testdata`` package (BSD-2; ``apt-get install pocketsphinx-testdata``) holds about 47 s of
16-kHz speech — five consecutive clips of a LibriVox volunteer reading *Sense and Sensibility* (public
domain), five clips of a man reading out card names, and three short CMU test utterances. Its TIDIGITS
clip is LDC data and is left out. Every recording is read speech with no acted emotion: a model should hear
it as neutral.

The clips of a group are joined in their order with 0.3 s of silence between them, so each group is one
recording of a single speaker, as a user would give it.
"""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE as SAMPLE_RATE, load_audio
from emogesture.errors import EmogestureError, InputFileError

#: Where Debian's ``pocketsphinx-testdata`` puts its recordings.
POCKETSPHINX_TESTDATA = Path("/usr/share/pocketsphinx/test/data")
GAP_SECONDS = 0.3


@dataclass(frozen=True)
class RealRecording:
    """One real recording: its clips (relative to the data folder), joined in order."""

    name: str
    description: str
    clips: tuple[str, ...]
    emotion: str = "neutral"  # read speech, no acted emotion


RECORDINGS: tuple[RealRecording, ...] = (
    RealRecording("librivox", "a LibriVox volunteer reading Sense and Sensibility (public domain), 5 consecutive "
                  "clips", tuple(f"librivox/sense_and_sensibility_01_austen_64kb-{n:04d}.wav"
                                 for n in (870, 880, 890, 920, 930))),
    RealRecording("cards", "a man reading out card names, 5 clips", tuple(f"cards/{n:03d}.wav" for n in range(1, 6))),
    RealRecording("cmu", "three CMU test utterances ('go forward', numbers, 'something')",
                  ("goforward.raw", "numbers.raw", "something.raw")),
)


def _read_clip(path: Path) -> np.ndarray:
    if path.suffix == ".raw":  # headerless 16-bit little-endian mono at 16 kHz
        data = np.fromfile(path, "<i2")
        if data.size == 0:
            raise InputFileError(path, "contains no audio samples")
        wave = data.astype(np.float32) / 32768.0
        return wave - wave.mean()
    return load_audio(path, target_sr=SAMPLE_RATE)[0]


def load_real_recording(recording: RealRecording, root: str | PathLike[str] = POCKETSPHINX_TESTDATA) -> np.ndarray:
    """The recording's clips joined with :data:`GAP_SECONDS` of silence -> a 16-kHz waveform ``[N]``."""
    root = Path(root)
    parts: list[np.ndarray] = []
    for clip in recording.clips:
        if parts:
            parts.append(np.zeros(int(GAP_SECONDS * SAMPLE_RATE), np.float32))
        path = root / clip
        if not path.is_file():
            raise InputFileError(path, "not found; install Debian's pocketsphinx-testdata")
        parts.append(_read_clip(path))
    return np.concatenate(parts).astype(np.float32)


def real_recordings(root: str | PathLike[str] = POCKETSPHINX_TESTDATA) -> list[RealRecording]:
    """The recordings whose clips are all present under ``root``; raises when there are none."""
    root = Path(root)
    found = [r for r in RECORDINGS if all((root / c).is_file() for c in r.clips)]
    if not found:
        raise EmogestureError(f"{root}: no real speech recordings found; install them with "
                              "`apt-get install pocketsphinx-testdata`")
    return found
