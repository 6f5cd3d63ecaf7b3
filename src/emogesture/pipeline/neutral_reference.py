"""A neutral reference: the speech's emotion heard against the same speaker's own neutral voice.

The perception places a window's emotion latent among the training voices' emotion means
(:mod:`emogesture.pipeline.perception`). A real person's even reading lies apart from all of them, nearest
whichever corpus emotion happens to lie in its direction: a lively reader sounds surprised, a flat one
contemptuous. From one recording alone nothing tells a lively voice from a surprised one. A second
recording of the same speaker speaking without emotion (``generate --neutral-from WAV``) says where that
speaker's neutral lies:

- the *offset* is the corpus's neutral mean minus the reference's mean emotion latent (for each hearing:
  as recorded and with the voice moved ``perception_semitones`` up and down, each against the reference
  heard the same way);
- the speech's windows moved by it (:meth:`NeutralReference.relative`) are the speech as if spoken by a
  voice whose neutral is the corpus's;
- what is heard is the mean of the hearings as recorded and moved
  (:func:`emogesture.pipeline.perception.heard_probabilities`), and the gesture model is given the moved
  emotion latents (under ``auto`` still blended toward neutral where they lie beyond the calibrated range).

Both hearings are kept because the moved one alone hears too little: the corpus's emotion prosody given to a
real voice moves its latent less than it moves a synthetic voice's, so moved alone most of a real reader's
windows given happiness or surprise are heard as neutral. The mean of the two hears a real reader's even
reading as neutral about ten times as often as the recording alone and the emotions given to it as often as
before, and the held-out synthetic voices under changed recordings better in every condition
(`experiments/neutral_reference.py`, val). The content and style latents, the timing and the classifier
head's logits are the speech's own (the head reads the encoder's class tokens, not the latent, so the
reading against the reference moves only the latent's part of :meth:`EmotionPerception.read`; beyond the
calibrated range, where the head reads alone, both hearings are the head's).

A reference is at least :data:`MIN_SECONDS` of sound (:func:`check_reference`): a shorter one is one window
padded with silence, whose latent is partly the padding's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from os import PathLike

import numpy as np

from emogesture.audio import TARGET_SAMPLE_RATE, check_speech
from emogesture.errors import EmogestureError
from emogesture.models.perception import EmotionPerception
from emogesture.pipeline.speech import EncodedWindows


MIN_SECONDS = 10.0  # one whole window


def check_reference(waveform: np.ndarray, source: str) -> None:
    """A one-line error naming ``source`` for a 16 kHz waveform ``[N]`` that cannot be a neutral reference:
    shorter than :data:`MIN_SECONDS`, or silent."""
    check_speech(waveform, TARGET_SAMPLE_RATE, source, min_seconds=MIN_SECONDS, allow_silence=False)


def reference_name(path: str | PathLike[str], span: tuple[float, float] | None = None) -> str:
    """How reports and messages name a neutral reference: the recording and, with ``span``, its seconds."""
    return str(path) + ("" if span is None else " {:g}-{:g} s".format(*span))


@dataclass(frozen=True)
class NeutralReference:
    """Where one speaker's neutral voice lies against the corpus's neutral mean."""

    source: str  # the reference recording, for reports
    offset: np.ndarray  # [D]: the corpus's neutral mean minus the reference's mean emotion latent
    #: [S, D]: the same for each pitch-moved hearing (EncodedWindows.shifted_emotion); None: heard once
    shifted_offsets: np.ndarray | None
    windows: int  # the reference's windows

    @classmethod
    def of(cls, enc: EncodedWindows, perception: EmotionPerception | None, source: str) -> "NeutralReference":
        """The reference of an encoded recording ``enc`` (emotion latents ``[R, D]``, pitch-moved hearings
        ``[S, R, D]``), against the corpus's neutral mean of ``perception``."""
        if perception is None:
            raise EmogestureError(f"{source}: a neutral reference needs a speech model with a perception "
                                  "calibration (emogesture calibrate speech); this one has none")
        if len(enc.emotion) == 0 or not enc.emotion.shape[-1]:
            raise EmogestureError(f"{source}: no emotion latents to take a neutral reference from")
        neutral = perception.neutral()
        offset = (neutral - enc.emotion.mean(0)).astype(np.float32)
        shifted = (None if enc.shifted_emotion is None else
                   (neutral[None] - enc.shifted_emotion.mean(1)).astype(np.float32))
        return cls(source, offset, shifted, len(enc.emotion))

    def relative(self, enc: EncodedWindows) -> EncodedWindows:
        """``enc`` with its emotion latents ``[W, D]`` (and pitch-moved hearings ``[S, W, D]``) moved by the
        offset; everything else (the logits too) as it is. Hearings the reference lacks take the offset as
        recorded."""
        kwargs = {"emotion": (enc.emotion + self.offset[None]).astype(np.float32)}
        if enc.shifted_emotion is not None:
            offsets = (self.shifted_offsets if self.shifted_offsets is not None
                       and len(self.shifted_offsets) == len(enc.shifted_emotion)
                       else np.broadcast_to(self.offset, (len(enc.shifted_emotion), len(self.offset))))
            kwargs["shifted_emotion"] = (enc.shifted_emotion + offsets[:, None]).astype(np.float32)
        return replace(enc, **kwargs)
