"""Inference policy on the emotion perception (:mod:`emogesture.models.perception`): what ``generate`` hears in
each window, and what ``--emotion auto`` gives the gesture model.

With ``--emotion auto`` (the default of ``emogesture generate``) a window's trust is the smaller of
the two, each 1 up to its threshold and falling linearly to 0 at twice the threshold; the window's
emotion latent is blended by ``1 − trust`` toward the latent of the emotion heard (where the perception reads the
front end trained on real speech, :mod:`emogesture.pipeline.voice_features`: the corpus's emotion means weighted
by what it hears), else toward the neutral mean. ``--emotion own`` keeps the raw latent.

The voice's own gesture style is kept in range the same way under ``auto``: a window's style latent is
blended by ``1 − voice trust`` toward a *fallback style*, one training speaker's mean style latent. A
style latent far from every training voice is an extrapolation for the gesture model: with the bundled
model of corpus version 3, real read speech (Debian's pocketsphinx-testdata) kept its arms hanging. Which
speaker matters as much, since the training speakers' gesture styles differ widely (a hand in front of
the chest in 5–81 % of the frames on the same recording). A gesture model that stores one
(``metadata.fallback_style``) names the speaker whose gestures are its typical ones, chosen on held-out
windows by motion (:mod:`emogesture.train.fallback_style`); otherwise the speech model's *typical
training style* stands in: the training speaker whose mean style latent lies nearest the centre of all
the speakers' means (:meth:`EmotionPerception.typical_speaker`). The nearest training speaker is not
used: the voice that a real recording happens to sound most like is no evidence of its gestures.
"""

from __future__ import annotations

import numpy as np

from emogesture.checkpoints import LoadedModel
from emogesture.errors import EmogestureError
from emogesture.models.perception import EmotionPerception, log_softmax
from emogesture.pipeline.perception_report import PerceivedEmotion
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder
from emogesture.types import EMOTIONS


def perception_of(encoder: SpeechLatentEncoder) -> EmotionPerception | None:
    """The emotion perception a speech model's file stores (None: it was never calibrated)."""
    return encoder.perception


#: how the two read-outs are combined where the front end heard a window (:func:`heard_probabilities`): the
#: log-probabilities of the read-out the perception leans on plus this share of the other's
OTHER_READOUT_WEIGHT = {"trusted": 0.5, "untrusted": 0.25}


def heard_probabilities(enc: EncodedWindows, perception: EmotionPerception | None,
                        relative: EncodedWindows | None = None) -> np.ndarray:
    """``[W, 8]`` over EMOTIONS: what the windows of ``enc`` sound like, :meth:`EmotionPerception.read` (the
    head's softmax if uncalibrated), averaged with the same windows heard with the voice moved in pitch
    where the encoder heard them so (``EncodedWindows.shifted_emotion``), and with ``relative``, the same
    windows read against a neutral reference (:mod:`emogesture.pipeline.neutral_reference`), heard alike:
    the mean of both. Where the front end trained on real speech heard the windows (:func:`heard_by_front_end`),
    both read-outs are multiplied: in a window the perception trusts fully, the speech model's log-probabilities
    plus half the front end's; elsewhere the front end's plus a quarter of the speech model's
    (:data:`OTHER_READOUT_WEIGHT`). Chosen on val against the front end deciding alone in the untrusted windows
    (the speech model's sharp readings of a real actor are mostly wrong, so it gets the small share there),
    mostly for what the speech model alone gets wrong within its trusted range: a recording 10 dB quieter heard
    as contempt, and real people reading aloud (``experiments/perception/README.md``, "Who decides the
    emotion heard")."""
    def read(emotion: np.ndarray, logits: np.ndarray) -> np.ndarray:
        return np.exp(log_softmax(logits) if perception is None else perception.read(emotion, logits))

    def hearings(e: EncodedWindows) -> np.ndarray:
        probs = read(e.emotion, e.emotion_logits)
        if e.shifted_emotion is None:
            return probs
        return np.mean([probs, *(read(s, lg) for s, lg in zip(e.shifted_emotion, e.shifted_logits))], axis=0)

    probs = hearings(enc)
    probs = probs if relative is None else 0.5 * (probs + hearings(relative))
    front = heard_by_front_end(enc, perception)
    if front is not None:
        animated = enc if relative is None else relative
        known = perception.trust(animated.emotion, animated.style) >= 1.0
        speech, heard = np.log(np.maximum(probs, 1e-30)), np.log(np.maximum(front, 1e-30))
        pooled = np.where(known[:, None], speech + OTHER_READOUT_WEIGHT["trusted"] * heard,
                          heard + OTHER_READOUT_WEIGHT["untrusted"] * speech)
        pooled = np.exp(pooled - pooled.max(1, keepdims=True))
        pooled /= pooled.sum(1, keepdims=True)
        probs = np.where(np.isfinite(front).all(1)[:, None], pooled, probs)  # (windows it did not hear: as read)
    return probs


def perceive(enc: EncodedWindows, starts_s: list[float], perception: EmotionPerception | None,
             source: str, relative: EncodedWindows | None = None,
             neutral_reference: str | None = None) -> PerceivedEmotion:
    """What is heard in each window of ``enc``; with ``relative`` (the same windows read against the neutral
    reference recording ``neutral_reference``), heard both ways (:func:`heard_probabilities`), and the
    distances and trust are those of the windows read against it, which the gesture model is given."""
    probs = heard_probabilities(enc, perception, relative)
    labels = [EMOTIONS[int(k)] for k in probs.argmax(1)]
    animated = enc if relative is None else relative
    distance = trust = None
    if perception is not None:
        distance = np.stack([perception.emotion.nearest(animated.emotion) / perception.emotion.threshold,
                             perception.voice.nearest(animated.style) / perception.voice.threshold], 1)
        trust = perception.trust(animated.emotion, animated.style)
    return PerceivedEmotion(source, list(starts_s), labels, probs, distance, trust,
                            real_voices=(None if perception is None
                                         else perception.real_voices_posterior(animated.emotion)),
                            noise_suppressed=enc.noise_suppressed, digital_silence_s=enc.digital_silence_s,
                            neutral_reference=neutral_reference)


def auto_emotion(emotion: np.ndarray, style: np.ndarray, perception: EmotionPerception | None,
                 heard: np.ndarray | None = None) -> np.ndarray:
    """Emotion latents ``[W, D]`` (with the same windows' style latents) moved into the corpus's frame where
    they lie near a real voices' mean (:meth:`EmotionPerception.in_corpus_frame`), then blended by ``1 − trust``
    toward the latent of the emotion heard, ``heard`` ``[W, 8]`` (the probabilities of the front end's
    read-out: :meth:`EmotionPerception.heard_latents`), or without it toward the neutral mean
    (``--emotion auto``); unchanged when the model has no perception calibration."""
    if perception is None:
        return emotion
    w = perception.trust(emotion, style)[:, None]
    target = np.broadcast_to(perception.neutral()[None], emotion.shape)
    if heard is not None:  # windows the front end did not hear keep the neutral
        heard_at = np.isfinite(heard).all(1)
        target = np.where(heard_at[:, None], perception.heard_latents(np.nan_to_num(heard)), target)
    return (w * perception.in_corpus_frame(emotion) + (1.0 - w) * target).astype(np.float32)


def heard_by_front_end(enc: EncodedWindows, perception: EmotionPerception | None) -> np.ndarray | None:
    """``[W, 8]``: what the front end trained on real speech hears in ``enc``'s windows, where it heard them
    (``EncodedWindows.heard_features``) and the perception reads it (NaN rows: windows it did not hear); else
    None."""
    if perception is None or perception.heard is None or enc.heard_features is None:
        return None
    return np.exp(perception.heard.log_probs(enc.heard_features))


def auto_style(style: np.ndarray, perception: EmotionPerception | None,
               fallback: np.ndarray | None = None) -> np.ndarray:
    """Style latents ``[W, D]`` blended toward ``fallback`` ``[D]`` (None: the speech model's typical training
    style) by ``1 − voice trust`` (``--emotion auto``; module docstring); unchanged when the model has no
    perception calibration."""
    if perception is None:
        return style
    target = perception.typical_style() if fallback is None else np.asarray(fallback, np.float32)
    if target.shape != style.shape[1:]:
        raise EmogestureError(f"fallback style has shape {target.shape}; the style latents are {style.shape[1:]}")
    w = perception.voice.trust(style)[:, None]
    return (w * style + (1.0 - w) * target[None]).astype(np.float32)


def fallback_style_of(gesture: LoadedModel) -> np.ndarray | None:
    """The style latent ``[D]`` a gesture model's unfamiliar voices fall back on, or None when it stores none."""
    record = getattr(gesture.metadata, "fallback_style", None)
    return None if not record else np.asarray(record["latent"], np.float32)
