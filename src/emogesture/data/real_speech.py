"""Real recorded speech for checks (never for training): what a user gives the tool.

No emotion-labelled real speech can be had here, but real recordings can, from two Debian packages:

- ``pocketsphinx-testdata`` (BSD-2) holds about 47 s of 16-kHz speech — five consecutive clips of a LibriVox
  volunteer reading *Sense and Sensibility* (public domain), five clips of a man reading out card names, and
  three short CMU test utterances. Its TIDIGITS clip is LDC data and is left out.
- ``asterisk-core-sounds-en-g722`` (CC BY-SA 3.0) holds the telephone-system prompts of the Asterisk PBX,
  recorded in a studio by a professional voice, Allison Smith, at 16 kHz (G.722); three of its longest
  prompts are used (about 67 s).

Every recording is read speech with no acted emotion: a model should hear it as neutral. (The prompts are
read in a warm, even, customer-service manner, brighter than the readers of the first package.) Either
package may be missing; :func:`real_recordings` returns what is installed.

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
#: Where Debian's ``asterisk-core-sounds-en-g722`` puts its English prompts.
ASTERISK_PROMPTS = Path("/usr/share/asterisk/sounds/en_US_f_Allison")
GAP_SECONDS = 0.3


@dataclass(frozen=True)
class RealRecording:
    """One real recording: its clips (relative to ``folder``, where Debian's ``package`` installs them), joined
    in order."""

    name: str
    description: str
    clips: tuple[str, ...]
    emotion: str = "neutral"  # read speech, no acted emotion
    folder: Path = POCKETSPHINX_TESTDATA
    package: str = "pocketsphinx-testdata"


RECORDINGS: tuple[RealRecording, ...] = (
    RealRecording("librivox", "a LibriVox volunteer reading Sense and Sensibility (public domain), 5 consecutive "
                  "clips", tuple(f"librivox/sense_and_sensibility_01_austen_64kb-{n:04d}.wav"
                                 for n in (870, 880, 890, 920, 930))),
    RealRecording("cards", "a man reading out card names, 5 clips", tuple(f"cards/{n:03d}.wav" for n in range(1, 6))),
    RealRecording("cmu", "three CMU test utterances ('go forward', numbers, 'something')",
                  ("goforward.raw", "numbers.raw", "something.raw")),
    RealRecording("prompts", "a professional voice (Allison Smith) reading three telephone-system prompts of the "
                  "Asterisk PBX (CC BY-SA 3.0)", ("demo-congrats.g722", "demo-echotest.g722", "demo-moreinfo.g722"),
                  folder=ASTERISK_PROMPTS, package="asterisk-core-sounds-en-g722"),
)


def _read_clip(path: Path) -> np.ndarray:
    if path.suffix == ".raw":  # headerless 16-bit little-endian mono at 16 kHz
        data = np.fromfile(path, "<i2")
        if data.size == 0:
            raise InputFileError(path, "contains no audio samples")
        wave = data.astype(np.float32) / 32768.0
        return wave - wave.mean()
    return load_audio(path, target_sr=SAMPLE_RATE)[0]


def load_real_recording(recording: RealRecording, root: str | PathLike[str] | None = None) -> np.ndarray:
    """The recording's clips (under ``root``; None: the recording's own folder) joined with :data:`GAP_SECONDS`
    of silence -> a 16-kHz waveform ``[N]``."""
    root = Path(root) if root is not None else recording.folder
    parts: list[np.ndarray] = []
    for clip in recording.clips:
        if parts:
            parts.append(np.zeros(int(GAP_SECONDS * SAMPLE_RATE), np.float32))
        path = root / clip
        if not path.is_file():
            raise InputFileError(path, f"not found; install Debian's {recording.package}")
        parts.append(_read_clip(path))
    return np.concatenate(parts).astype(np.float32)


def real_recordings(root: str | PathLike[str] | None = None) -> list[RealRecording]:
    """The recordings whose clips are all present, each in its own folder (or all under ``root``); raises
    when there are none."""
    def folder(r: RealRecording) -> Path:
        return Path(root) if root is not None else r.folder

    found = [r for r in RECORDINGS if all((folder(r) / c).is_file() for c in r.clips)]
    if not found:
        where = root if root is not None else ", ".join(sorted({str(r.folder) for r in RECORDINGS}))
        packages = " ".join(dict.fromkeys(r.package for r in RECORDINGS))
        raise EmogestureError(f"{where}: no real speech recordings found; install them with "
                              f"`apt-get install {packages}`")
    return found
