"""The speech's phones and their times, from pocketsphinx's US-English models (BSD-2, inside its wheel).

Without a transcript the phones are recognised (pocketsphinx's phone-loop search with its phone trigram
model); with one, the words are forced-aligned and their dictionary phones timed. Long recordings are heard
in pieces of about :data:`PIECE_S` seconds, cut at the quietest moment near each boundary.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emogesture.errors import EmogestureError

PIECE_S = 20.0  # s: the longest stretch heard at once
SAMPLE_RATE = 16000  # Hz: what the acoustic model was trained on
_FRAME_S = 0.01  # s: pocketsphinx's frame


@dataclass(frozen=True)
class Phone:
    """One phone: its ARPAbet name (no stress digit; ``SIL`` for silence) and its span in seconds."""

    name: str
    start: float
    end: float


def recogniser_installed() -> bool:
    """Whether pocketsphinx and its models can be imported."""
    try:
        import pocketsphinx  # noqa: F401
    except ImportError:
        return False
    return True


def _pieces(waveform: np.ndarray, sample_rate: int) -> list[tuple[int, int]]:
    """Cut ``[N]`` into spans of at most about PIECE_S, each cut at the quietest 10 ms within 2 s before it."""
    n, piece, hop = len(waveform), int(PIECE_S * sample_rate), int(_FRAME_S * sample_rate)
    spans, start = [], 0
    while n - start > piece:
        lo = start + piece - 2 * sample_rate
        frames = waveform[lo : start + piece][: (2 * sample_rate // hop) * hop].reshape(-1, hop)
        cut = lo + int(np.argmin((frames ** 2).mean(1))) * hop + hop // 2
        spans.append((start, cut))
        start = cut
    spans.append((start, n))
    return spans


def _pcm(waveform: np.ndarray) -> bytes:
    return (np.clip(waveform, -1.0, 1.0) * 32767).astype("<i2").tobytes()


def recognise_phones(waveform: np.ndarray, sample_rate: int = SAMPLE_RATE,
                     transcript: str | None = None) -> list[Phone]:
    """A mono waveform ``[N]`` at 16 kHz -> its phones in time order, covering the recording.

    ``transcript``: the words spoken (any case and punctuation); they are forced-aligned to the whole
    recording instead of recognised, and words the dictionary lacks are skipped. Raises
    :class:`~emogesture.errors.EmogestureError` when pocketsphinx is not installed or the rate is not 16 kHz.
    """
    if sample_rate != SAMPLE_RATE:
        raise EmogestureError(f"the phone recogniser needs {SAMPLE_RATE} Hz audio, got {sample_rate}")
    try:
        from pocketsphinx import Decoder, get_model_path
    except ImportError as e:
        raise EmogestureError("the face's phones need pocketsphinx (pip install pocketsphinx)") from e
    waveform = np.asarray(waveform, np.float32)
    if transcript is not None:
        return _aligned(Decoder, waveform, transcript)
    decoder = Decoder(allphone=get_model_path("en-us/en-us-phone.lm.bin"), lw=2.0, bestpath=False,
                      loglevel="FATAL")
    phones: list[Phone] = []
    for a, b in _pieces(waveform, sample_rate):
        decoder.start_utt()
        decoder.process_raw(_pcm(waveform[a:b]), full_utt=True)
        decoder.end_utt()
        offset = a / sample_rate
        phones += [Phone(s.word, offset + s.start_frame * _FRAME_S, offset + (s.end_frame + 1) * _FRAME_S)
                   for s in decoder.seg()]
    return phones


def _aligned(decoder_class, waveform: np.ndarray, transcript: str) -> list[Phone]:
    """The transcript's words forced-aligned to the whole recording, as their phones."""
    decoder = decoder_class(bestpath=False, loglevel="FATAL")
    words = ["".join(c for c in w if c.isalpha() or c == "'") for w in transcript.lower().split()]
    known = [w for w in words if w and decoder.lookup_word(w) is not None]
    if not known:
        raise EmogestureError("none of the transcript's words is in the pronouncing dictionary")
    pcm = _pcm(waveform)
    decoder.set_align_text(" ".join(known))
    for _ in range(2):  # the words' alignment first, then their phones' and states'
        decoder.start_utt()
        decoder.process_raw(pcm, full_utt=True)
        decoder.end_utt()
        if _ == 0:
            decoder.set_alignment()
    alignment = decoder.get_alignment()
    if alignment is None:
        raise EmogestureError("the transcript could not be aligned to the recording")
    return [Phone(p.name, p.start * _FRAME_S, (p.start + p.duration) * _FRAME_S)
            for word in alignment for p in word]
