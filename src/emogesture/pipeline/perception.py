"""Emotion perception: which emotion the speech model hears in each window, and whether its emotion
latent can be trusted there.

The speech model learns emotion from the training voices only. On a voice unlike them (a real
recording, another synthesiser, a telephone line, noise) its emotion latent can say an emotion nobody
spoke, and the gesture model would animate it. So a speech model carries, in its
``metadata.emotion_perception``, where its latents lie on training speech, for two latents:

- the **emotion** latent around the mean latent of each emotion, and the **style** latent (the voice)
  around the mean latent of each training speaker;
- a window's distance is a Mahalanobis distance to the nearest mean, with the pooled within-class
  covariance (Ledoit–Wolf shrunk, kept as 32 principal axes plus one variance for the rest,
  :class:`LatentRange`), about 1 for typical training windows;
- each *threshold* is a high quantile (default 0.99) of that distance over held-out windows (texts the
  speech model never trained on), so about 1 % of in-distribution windows exceed it.

The voice is what tells unfamiliar speech apart: measured on held-out takes played through changes, the
style distance flags most windows of a voice 4 semitones lower, of a telephone band, of speech in
white noise and of noise alone, where the emotion distance flags few (`experiments/reports/bundled_model/`).

The emotion a window is *heard* as (its label, and the probabilities ``generate`` reports) is read
off both of the model's views of it (:meth:`EmotionPerception.read`): the classifier head's
log-probabilities, plus, where the window's emotion latent lies within the calibrated range (emotion
distance at most its threshold), the log-posterior of the nearest emotion mean in that same distance
(a linear discriminant with equal priors). Within the range either can decide where the other is
unsure; beyond it the means say little and the head decides alone. The sum is divided by a
temperature fitted on the held-out windows within the range (their mean negative log-likelihood), so
that its probabilities say how often it is right there (the posterior of the means alone, over a
latent of many dimensions, is near 0 or 1 everywhere); the division changes no label. Chosen on the
val split's held-out voices under changed recording conditions, against the head alone and the sum
everywhere or weighted by the trust (`experiments/reports/speech_tuned/perception_readout_val.md`).

A voice pitched unlike the training voices is read partly by its pitch: the corpus gives its emotions
their own pitch, so a voice moved 4 semitones down sounds sadder or more contemptuous to the model. The
generation setting ``perception_semitones`` (3 by default) has the emotion encoder hear each window
three times, as recorded and with the voice (pitch and formants, tempo kept) moved that many semitones up
and down; the probabilities reported are the mean of the three readings (:func:`heard_probabilities`). On
the val split's held-out voices this was right more often in every pitch condition and as recorded
(`experiments/reports/perception_hearings/`). Only what is heard changes; the trust and the latents the
gesture model is given are the recording's own.

A real voice lies apart from the synthetic training voices in the emotion latent as well, so the corpus's
emotion means alone place a real person's even reading nearest whichever corpus emotion happens to lie in
that direction (happiness or surprise for a warm professional voice, contempt for a flat reader). A
calibration with real voices (``emogesture calibrate speech --real-voices fr_june,it_carlo,ru_ivr``; the
voices of :data:`emogesture.data.real_speech.TRAINING_VOICES`, never the checks') gives each emotion a second
mean: of those voices' stretches, as recorded for neutral and given each other emotion's speech prosody as
the corpus gives it (:func:`emogesture.data.real_speech.training_voice_emotions`). An emotion's posterior
sums over its means; the spread, the neutral mean that ``auto`` blends toward and the voice range stay the
corpus's. Only the studio voices are used: the 8-kHz telephone voices would draw the held-out voices heard
through a telephone band toward their means. What ``auto`` animates follows what is heard: a window near a
real voices' mean has its emotion latent moved by the offset from that mean to the corpus's mean of the same
emotion (:meth:`EmotionPerception.in_corpus_frame`), so the gesture model gets the latent of the emotion heard
in a place it learned, not the real voice's own.

A telephone band (below 300 Hz and above 3.4 kHz taken away) moves every window's emotion latent; the
corpus's emotion means alone then read held-out voices played through a simulated telephone band
(:func:`emogesture.audio.wave_augment.telephone`) right less often than the same voices as recorded. A calibration with ``--telephone-means`` gives each
emotion one more mean, of the training takes heard through a telephone band (:func:`telephone_band_latents`),
which only the read-out uses (:meth:`EmotionPerception.read_range`: the head plus the posterior summed over
each emotion's means, within the same threshold). The trust, the neutral mean and the latents ``auto``
animates stay the corpus's: such a recording is heard better, not animated differently
(`experiments/README.md`, "Telephone-band means"; measured on that simulated band only, as no real telephone
recording with a known emotion is at hand).

With ``--emotion auto`` (the default of ``emogesture generate``) a window's trust is the smaller of
the two, each 1 up to its threshold and falling linearly to 0 at twice the threshold; the window's
emotion latent is blended toward the neutral mean by ``1 − trust``. ``--emotion own`` keeps the raw latent.

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

import json
from collections import Counter
from pathlib import Path
from dataclasses import dataclass, field, replace
from os import PathLike

import numpy as np
from tqdm import tqdm

from emogesture.audio import load_audio
from emogesture.audio.wave_augment import telephone
from emogesture.checkpoints import (LoadedModel, check_model_output, load_model, refuse_trained_split, save_model,
                                    stored_weights_dtype, trained_splits)
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.data.real_speech import TRAINING_VOICES, training_voice_emotions
from emogesture.data.synthetic.corpus import corpus_emotion_prosody_scale
from emogesture.diffusion.residual import shrunk_covariance
from emogesture.errors import EmogestureError
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder

TRUST_QUANTILE = 0.99
COMPONENTS = 32
REAL_STRETCHES = 10  # per real voice, when the perception learns real voices' emotions


def log_softmax(x: np.ndarray) -> np.ndarray:
    """Row-wise log-softmax of scores ``[W, K]``."""
    x = np.asarray(x, np.float64)
    x = x - x.max(1, keepdims=True)
    return x - np.log(np.exp(x).sum(1, keepdims=True))


def class_means(latents: np.ndarray, labels: np.ndarray) -> tuple[list[int], np.ndarray]:
    """The classes present in ``labels`` ``[N]`` (sorted) and each one's mean of ``latents`` ``[N, D]``
    -> (classes, means ``[K, D]``, in the latents' dtype)."""
    labels = np.asarray(labels)
    classes = sorted(set(labels.tolist()))
    return classes, np.stack([latents[labels == k].mean(0) for k in classes])


@dataclass
class LatentRange:
    """Where one latent lies on training speech: class means and a Mahalanobis distance to the nearest.

    The within-class covariance (Ledoit–Wolf shrunk) is kept as its ``k`` leading principal axes
    ``axes [k, D]`` with their variances, and one variance ``rest`` for the other ``D − k`` directions
    (a probabilistic-PCA approximation, small enough to store as JSON). The distance of ``z`` to a class
    mean ``μ`` is ``sqrt((Σᵢ (aᵢ·(z−μ))² / λᵢ + |residual|² / rest) / D)``: about 1 for typical
    training windows, whatever the latent's scale.
    """

    means: np.ndarray  # [K, D]
    axes: np.ndarray  # [k, D]
    variances: np.ndarray  # [k]
    rest: float
    threshold: float = 1.0  # distance above which trust starts to fall

    @classmethod
    def fit(cls, latents: np.ndarray, labels: np.ndarray, components: int = COMPONENTS) -> "LatentRange":
        x = np.asarray(latents, np.float64)
        classes, means = class_means(x, labels)
        cov, _ = shrunk_covariance(x - means[np.searchsorted(classes, labels)])
        values, vectors = np.linalg.eigh(cov)
        values, vectors = values[::-1], vectors[:, ::-1]
        k = min(components, x.shape[1] - 1)
        return cls(means, vectors[:, :k].T.copy(), values[:k].copy(), float(values[k:].mean()))

    def distances(self, latents: np.ndarray) -> np.ndarray:
        """Latents ``[W, D]`` -> distance to each class mean ``[W, K]``."""
        d = np.asarray(latents, np.float64)[:, None, :] - self.means[None]
        along = d @ self.axes.T
        residual = (d * d).sum(-1) - (along * along).sum(-1)
        return np.sqrt(((along * along / self.variances).sum(-1) + residual.clip(0) / self.rest) / d.shape[-1])

    def nearest(self, latents: np.ndarray) -> np.ndarray:
        return self.distances(latents).min(1)

    def log_posteriors(self, latents: np.ndarray) -> np.ndarray:
        """Latents ``[W, D]`` -> log-posteriors ``[W, K]`` of the class means: equal priors and this range's
        shared covariance (a linear discriminant), ``log softmax(−D d² / 2)`` of the distances ``d``."""
        return log_softmax(-0.5 * np.shape(latents)[1] * self.distances(latents) ** 2)

    def trust(self, latents: np.ndarray) -> np.ndarray:
        """``[W]`` in [0, 1]: 1 up to the threshold, falling linearly to 0 at twice the threshold."""
        return np.clip(2.0 - self.nearest(latents) / self.threshold, 0.0, 1.0)

    def to_dict(self) -> dict:
        return {"means": self.means.tolist(), "axes": self.axes.tolist(), "variances": self.variances.tolist(),
                "rest": self.rest, "threshold": self.threshold}

    @classmethod
    def from_dict(cls, d: dict) -> "LatentRange":
        return cls(*(np.asarray(d[k], np.float64) for k in ("means", "axes", "variances")), float(d["rest"]),
                   float(d["threshold"]))


@dataclass
class EmotionPerception:
    """Where a speech model's emotion and style latents lie on its training speech (module docstring)."""

    labels: list[str]  # the emotion of each of ``emotion.means`` (an emotion may have several: real voices')
    emotion: LatentRange  # emotion latent around the emotion means
    voice: LatentRange  # style latent around the training speakers' means
    info: dict  # how it was measured (splits, windows, quantile)
    temperature: float = 1.0  # divides the read-out's summed log-probabilities within the range (read)
    #: the emotion of each of ``band_means``: each emotion's mean of the training windows heard through a
    #: telephone band, which only the read-out uses (module docstring); empty without them
    band_labels: list[str] = field(default_factory=list)
    band_means: np.ndarray | None = None  # [B, D]

    def trust(self, emotion: np.ndarray, style: np.ndarray) -> np.ndarray:
        """Per-window trust ``[W]``: the smaller of the emotion's and the voice's."""
        return np.minimum(self.emotion.trust(emotion), self.voice.trust(style))

    def read_range(self) -> LatentRange:
        """The emotion range the read-out uses: :attr:`emotion` with the telephone band's means beside its own
        (the same spread and threshold); :attr:`emotion` itself without them."""
        if self.band_means is None or not len(self.band_labels):
            return self.emotion
        return replace(self.emotion, means=np.concatenate([self.emotion.means, self.band_means]))

    def summed(self, emotion: np.ndarray, logits: np.ndarray) -> np.ndarray:
        """The head's log-probabilities plus the emotion means' log-posteriors, ``[W, 8]`` over ``EMOTIONS``
        (an emotion with several means, the real voices' and the telephone band's: their posteriors summed;
        one the calibration never saw has no mean: ``-inf``), from emotion latents ``[W, D]`` and head logits
        ``[W, 8]``; neither tempered nor renormalised."""
        means = np.full((len(logits), len(EMOTIONS)), -np.inf)
        labels = self.labels + self.band_labels
        for label, posterior in zip(labels, self.read_range().log_posteriors(emotion).T):
            k = EMOTIONS.index(label)
            means[:, k] = np.logaddexp(means[:, k], posterior)
        return log_softmax(logits) + means

    def read(self, emotion: np.ndarray, logits: np.ndarray) -> np.ndarray:
        """The emotion heard in each window, as log-probabilities ``[W, 8]`` over ``EMOTIONS``, from the
        windows' emotion latents ``[W, D]`` and classifier-head logits ``[W, 8]``: :meth:`summed` divided by
        :attr:`temperature` and renormalised where the emotion latent lies within the calibrated range, the
        head's alone elsewhere (module docstring)."""
        inside = self.read_range().nearest(emotion) <= self.emotion.threshold
        if not inside.any():
            return log_softmax(logits)
        return np.where(inside[:, None], log_softmax(self.summed(emotion, logits) / self.temperature),
                        log_softmax(logits))

    def _extra_means(self) -> list[int]:
        """Indices of the means after each emotion's first (the real voices')."""
        return [j for j, label in enumerate(self.labels) if self.labels.index(label) != j]

    def real_voices_posterior(self, emotion: np.ndarray) -> np.ndarray | None:
        """``[W]``: the posterior of the real voices' means of emotion latents ``[W, D]``; None without them."""
        extra = self._extra_means()
        if not extra:
            return None
        return np.exp(self.emotion.log_posteriors(emotion))[:, extra].sum(1)

    def in_corpus_frame(self, emotion: np.ndarray) -> np.ndarray:
        """Emotion latents ``[W, D]`` with what a real voice adds taken away: each window moved by the offset
        from the real voices' mean of each emotion to the corpus's mean of it, weighted by the posterior of
        that real mean (so a real voice's even reading lands near the corpus's neutral mean, where the gesture
        model learned neutral motion, and a window near a corpus mean stays where it is). Unchanged without
        real voices' means."""
        first = {label: self.labels.index(label) for label in self.labels}
        extra = self._extra_means()
        emotion = np.asarray(emotion)
        if not extra:
            return emotion
        posterior = np.exp(self.emotion.log_posteriors(emotion))[:, extra]  # [W, R]
        offsets = np.stack([self.emotion.means[first[self.labels[j]]] - self.emotion.means[j] for j in extra])
        return (emotion + posterior @ offsets).astype(emotion.dtype)

    def neutral(self) -> np.ndarray:
        """The neutral mean of the training corpus ``[D]`` (the first; real voices' means come after)."""
        return self.emotion.means[self.labels.index("neutral")]

    def typical_speaker(self) -> int:
        """Index (into ``voice.means``) of the training speaker whose mean style latent lies nearest the
        centre of all the speakers' means, in the voice's own distance."""
        return int(self.voice.distances(self.voice.means.mean(0, keepdims=True))[0].argmin())

    def typical_style(self) -> np.ndarray:
        """The mean style latent ``[D]`` of :meth:`typical_speaker`."""
        return self.voice.means[self.typical_speaker()]

    def to_dict(self) -> dict:
        d = {"labels": list(self.labels), "emotion": self.emotion.to_dict(), "voice": self.voice.to_dict(),
             "info": self.info, "temperature": self.temperature}
        if self.band_means is not None:
            d.update(band_labels=list(self.band_labels), band_means=self.band_means.tolist())
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "EmotionPerception":
        band = d.get("band_means")
        if band is not None:
            band = np.asarray(band, np.float64)
            means = np.asarray(d["emotion"]["means"])
            if band.ndim != 2 or band.shape[1:] != means.shape[1:] or len(band) != len(d.get("band_labels", [])):
                raise EmogestureError(f"emotion perception: {len(d.get('band_labels', []))} telephone-band labels for "
                                      f"telephone-band means of shape {band.shape}; the emotion means are "
                                      f"{means.shape}")
        return cls(list(d["labels"]), LatentRange.from_dict(d["emotion"]), LatentRange.from_dict(d["voice"]),
                   dict(d.get("info", {})), float(d.get("temperature", 1.0)), list(d.get("band_labels", [])),
                   band)


def fit_perception(train: EncodedWindows, emotions: np.ndarray, speakers: np.ndarray, held_out: EncodedWindows,
                   quantile: float = TRUST_QUANTILE, held_out_emotions: np.ndarray | None = None,
                   real: EncodedWindows | None = None, real_emotions: np.ndarray | None = None,
                   band: EncodedWindows | None = None, band_emotions: np.ndarray | None = None) -> EmotionPerception:
    """Emotion means (by ``emotions`` ``[N]``, indices into ``EMOTIONS``) and speaker means (by
    ``speakers`` ``[N]``) with their within-class spread from training windows; each threshold is the
    ``quantile`` of the held-out windows' distances; with the held-out windows' emotions ``[M]``, the
    read-out's temperature is fitted on those within the range (:func:`fit_temperature`). With ``real``
    windows of real voices given the corpus's emotions (``real_emotions`` ``[R]``), each of their emotions
    gets a second mean beside the corpus's (the spread stays the training windows'). With ``band`` windows
    (training speech heard through a telephone band, emotions ``band_emotions`` ``[B]``), each of their
    emotions gets a mean that only the read-out uses (:meth:`EmotionPerception.read_range`)."""
    emotions, speakers = np.asarray(emotions), np.asarray(speakers)
    present = sorted(set(emotions.tolist()))
    if EMOTIONS.index("neutral") not in present:
        raise EmogestureError("emotion perception needs neutral training windows")
    labels = [EMOTIONS[k] for k in present]
    emotion = LatentRange.fit(train.emotion, emotions)
    if real is not None:
        heard, real_means = class_means(real.emotion, real_emotions)
        emotion.means = np.concatenate([emotion.means, real_means])
        labels += [EMOTIONS[k] for k in heard]
    voice = LatentRange.fit(train.style, speakers)
    d_emotion, d_voice = emotion.nearest(held_out.emotion), voice.nearest(held_out.style)
    emotion.threshold = float(np.quantile(d_emotion, quantile))
    voice.threshold = float(np.quantile(d_voice, quantile))
    info = {"train_windows": int(len(emotions)), "held_out_windows": int(len(d_emotion)), "quantile": float(quantile),
            "held_out_distance_median": {"emotion": float(np.median(d_emotion)), "voice": float(np.median(d_voice))}}
    if real is not None:
        info["real_windows"] = int(len(real_emotions))
    perception = EmotionPerception(labels, emotion, voice, info)
    if band is not None:
        heard, perception.band_means = class_means(np.asarray(band.emotion, np.float64), band_emotions)
        perception.band_labels = [EMOTIONS[k] for k in heard]
        info["band_windows"] = int(len(band_emotions))
    if held_out_emotions is not None:
        inside = d_emotion <= emotion.threshold
        perception.temperature = fit_temperature(perception, held_out.emotion[inside], held_out.emotion_logits[inside],
                                                 np.asarray(held_out_emotions)[inside])
        info["temperature_windows"] = int(inside.sum())
    return perception


def fit_temperature(perception: EmotionPerception, emotion: np.ndarray, logits: np.ndarray,
                    labels: np.ndarray) -> float:
    """The temperature (0.5-1000) that minimises the mean negative log-likelihood of ``labels`` ``[M]``
    (indices into ``EMOTIONS``) under the read-out's summed log-probabilities of windows within the range
    (emotion latents ``[M, D]``, head logits ``[M, 8]``); 1 without windows."""
    from scipy.optimize import minimize_scalar

    if len(labels) == 0:
        return 1.0
    summed = perception.summed(emotion, logits)
    rows = np.arange(len(labels))

    def nll(log_t: float) -> float:
        lp = log_softmax(summed / np.exp(log_t))[rows, labels]
        return float(-np.maximum(lp, -1e3).mean())  # a label the means never saw: a bounded penalty

    best = minimize_scalar(nll, bounds=(np.log(0.5), np.log(1000.0)), method="bounded")
    return float(np.exp(best.x))


def perception_of(encoder: SpeechLatentEncoder) -> EmotionPerception | None:
    stored = encoder.loaded.metadata.emotion_perception
    return EmotionPerception.from_dict(stored) if stored else None


@dataclass
class PerceivedEmotion:
    """What the speech model heard in each window of one audio."""

    source: str
    starts_s: list[float]
    labels: list[str]  # per window, the emotion heard (the most probable)
    probabilities: np.ndarray  # [W, 8] over EMOTIONS: EmotionPerception.read (the head's softmax if uncalibrated)
    distance: np.ndarray | None  # [W, 2] emotion / voice distance over its threshold (None: not calibrated)
    trust: np.ndarray | None  # [W]
    #: per window, the emotion animated instead, where a timeline says (keyframe name -> share of the window)
    in_force: list[dict[str, float]] | None = None
    #: [W] per window, the posterior of the real voices' means (None: the calibration has none)
    real_voices: np.ndarray | None = None
    #: how much of the recording's steady background noise was taken out before it was heard (0–1)
    noise_suppressed: float = 0.0
    #: seconds of digital silence (exact zeros) heard as the recording's own quiet
    digital_silence_s: float = 0.0
    #: the recording of the same speaker's neutral voice the windows were read against (None: none)
    neutral_reference: str | None = None

    @property
    def majority(self) -> tuple[str, int]:
        return Counter(self.labels).most_common(1)[0]

    @property
    def confidence(self) -> float:
        """Mean probability of the majority emotion over the windows."""
        label, _ = self.majority
        return float(self.probabilities[:, EMOTIONS.index(label)].mean())

    @property
    def unlike_training_voices(self) -> bool:
        """Whether at least half the windows lie beyond the calibrated range or nearer the real voices' means
        than the corpus's (False without a calibration)."""
        if self.trust is None:
            return False
        real = int((self.real_voices > 0.5).sum()) if self.real_voices is not None else 0
        return 2 * max(real, int((self.trust < 1.0).sum())) >= len(self.labels)

    def summary(self, mode: str) -> str:
        """One line: the emotion heard, how, and what ``mode`` (``auto``/``own``) does about windows beyond
        the calibrated range."""
        label, count = self.majority
        n = len(self.labels)
        text = (f"{self.source}: perceived emotion {label} ({count} of {n} window{'s' * (n != 1)}, "
                f"mean probability {self.confidence:.2f})")
        if self.noise_suppressed > 0:
            text += f", heard with its steady background noise taken out ({self.noise_suppressed:.0%})"
        if self.digital_silence_s > 0:
            text += f", its {self.digital_silence_s:.1f} s of digital silence heard as the recording's own quiet"
        if self.neutral_reference is not None:
            text += f", read against the speaker's neutral voice in {self.neutral_reference}"
        if self.trust is None:
            return text + "; this speech model has no perception calibration, its emotion latent is used as is"
        low = int((self.trust < 1.0).sum())
        real = int((self.real_voices > 0.5).sum()) if self.real_voices is not None else 0
        if mode == "auto" and real:
            text += (f"; {real} of {n} windows sound more like the real voices the perception knows than the training "
                     "voices and are animated with the training voices' latent of the emotion heard")
        if mode == "auto" and low:
            far_voice = int((self.distance[:, 1] > 1.0).sum())
            style = (f", and in {far_voice} the voice is unlike every training voice, so its gesture style is blended "
                     "toward the gesture model's fallback style") if far_voice else ""
            return (text + f"; in {low} of {n} windows the voice or its emotion is unlike the training speech "
                    f"(beyond the calibrated range), so their emotion is blended toward neutral{style} "
                    "(--emotion own keeps both)")
        if low:
            return text + f"; {low} of {n} windows lie outside the training voices' range (kept: --emotion own)"
        return text + "; every window within the training voices' range"

    def to_json(self) -> str:
        rows = []
        for i, start in enumerate(self.starts_s):
            row = {"start_s": round(float(start), 3), "end_s": round(float(start) + 10.0, 3),
                   "emotion": self.labels[i],
                   "probabilities": {k: round(float(v), 4) for k, v in zip(EMOTIONS, self.probabilities[i])}}
            if self.distance is not None:
                row["emotion_distance"] = round(float(self.distance[i, 0]), 4)
                row["voice_distance"] = round(float(self.distance[i, 1]), 4)
                row["trust"] = round(float(self.trust[i]), 4)
            if self.real_voices is not None:
                row["real_voices"] = round(float(self.real_voices[i]), 4)
            if self.in_force is not None:
                row["animated_emotion"] = self.in_force[i]
            rows.append(row)
        label, count = self.majority
        head = {"source": self.source, "emotion": label, "windows_agreeing": count,
                "confidence": round(self.confidence, 4), "noise_suppressed": round(float(self.noise_suppressed), 4),
                "digital_silence_s": round(float(self.digital_silence_s), 2)}
        if self.neutral_reference is not None:
            head["neutral_reference"] = self.neutral_reference
        return json.dumps({**head, "windows": rows}, indent=1) + "\n"


def heard_probabilities(enc: EncodedWindows, perception: EmotionPerception | None,
                        relative: EncodedWindows | None = None) -> np.ndarray:
    """``[W, 8]`` over EMOTIONS: what the windows of ``enc`` sound like, :meth:`EmotionPerception.read` (the
    head's softmax if uncalibrated), averaged with the same windows heard with the voice moved in pitch
    where the encoder heard them so (``EncodedWindows.shifted_emotion``), and with ``relative``, the same
    windows read against a neutral reference (:mod:`emogesture.pipeline.neutral_reference`), heard alike:
    the mean of both."""
    def read(emotion: np.ndarray, logits: np.ndarray) -> np.ndarray:
        return np.exp(log_softmax(logits) if perception is None else perception.read(emotion, logits))

    def hearings(e: EncodedWindows) -> np.ndarray:
        probs = read(e.emotion, e.emotion_logits)
        if e.shifted_emotion is None:
            return probs
        return np.mean([probs, *(read(s, lg) for s, lg in zip(e.shifted_emotion, e.shifted_logits))], axis=0)

    probs = hearings(enc)
    return probs if relative is None else 0.5 * (probs + hearings(relative))


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


def auto_emotion(emotion: np.ndarray, style: np.ndarray, perception: EmotionPerception | None) -> np.ndarray:
    """Emotion latents ``[W, D]`` (with the same windows' style latents) moved into the corpus's frame where
    they lie near a real voices' mean (:meth:`EmotionPerception.in_corpus_frame`), then blended toward the
    neutral mean by ``1 − trust`` (``--emotion auto``); unchanged when the model has no perception calibration."""
    if perception is None:
        return emotion
    w = perception.trust(emotion, style)[:, None]
    return (w * perception.in_corpus_frame(emotion) + (1.0 - w) * perception.neutral()[None]).astype(np.float32)


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


def calibrate_perception_run(run: str | PathLike[str], cache_dir: str | PathLike[str], out: str | PathLike[str],
                             split: str = "val", quantile: float = TRUST_QUANTILE, overwrite: bool = False,
                             real_voices: list[str] | tuple[str, ...] = (),
                             real_stretches: int = REAL_STRETCHES, telephone_means: bool = False) -> EmotionPerception:
    """Write a copy of the speech model of ``run`` to ``out`` with its emotion perception: means and
    spread from the cache's ``train`` windows, the threshold from ``split`` (which the model must not
    have trained on; its run records the training splits). With ``real_voices`` (names of
    :data:`emogesture.data.real_speech.TRAINING_VOICES`), also means of those real voices given each of the
    synthetic corpus's emotions (``real_stretches`` 10-s stretches of each; module docstring). With
    ``telephone_means``, also each emotion's mean of the ``train`` takes heard through a telephone band, for the
    read-out only (:func:`telephone_band_latents`)."""
    if not 0.5 <= quantile < 1.0:
        raise EmogestureError(f"quantile {quantile}: must be in [0.5, 1)")
    if split in ("train", "test"):
        raise EmogestureError(f"--split {split}: calibrate on held-out windows that are not the test split (e.g. val)")
    unknown = [v for v in real_voices if v not in TRAINING_VOICES]
    if unknown:
        raise EmogestureError(f"real voice {unknown[0]!r}: unknown; known: {', '.join(TRAINING_VOICES)}")
    check_model_output(out, overwrite)
    loaded = load_model(run, "speech")
    trained_on = trained_splits(loaded)
    refuse_trained_split(split, loaded, purpose="calibrate")
    encoder = SpeechLatentEncoder(loaded)
    cache = open_cache(cache_dir)
    train = encoder.encode_split(cache, "train")
    held = encoder.encode_split(cache, split)
    windows = cache.split("train")
    real = real_emotions = None
    if real_voices:
        root = Path(cache.manifest["root"])
        try:
            scale = corpus_emotion_prosody_scale(root)
        except (OSError, KeyError, ValueError) as e:
            raise EmogestureError(f"{root}: real voices are given the emotions of a synthetic corpus, and this "
                                  f"cache's corpus is not one ({e})") from None
        real, real_emotions = real_voice_latents(encoder, list(real_voices), real_stretches, scale)
    band = band_emotions = None
    if telephone_means:
        band, band_emotions = telephone_band_latents(encoder, cache)
    perception = fit_perception(train, windows.emotion, windows.speaker_id, held, quantile,
                                held_out_emotions=cache.split(split).emotion, real=real, real_emotions=real_emotions,
                                band=band, band_emotions=band_emotions)
    perception.info.update(split=split, trained_on=trained_on)
    if real_voices:
        perception.info.update(real_voices=list(real_voices), real_stretches=int(real_stretches))
    metadata = loaded.metadata.replace(train_splits=trained_on, emotion_perception=perception.to_dict())
    save_model(out, "speech", loaded.model, loaded.config, metadata, weights_dtype=stored_weights_dtype(loaded))
    return perception


def telephone_band_latents(encoder: SpeechLatentEncoder, cache, split: str = "train",
                           hop_seconds: float = 8.0) -> tuple[EncodedWindows, np.ndarray]:
    """Every take of a cache's ``split`` heard through a telephone band
    (:func:`emogesture.audio.wave_augment.telephone`: 300–3400 Hz, 8 kHz, μ-law), in 10-s windows every
    ``hop_seconds`` -> their windows' emotion latents and logits, and each window's emotion ``[N]``."""
    root = Path(cache.manifest["root"])
    encoded, emotions = [], []
    takes = cache.split(split).take_emotions()
    for take, emotion in tqdm(takes.items(), total=len(takes), desc="train takes through a telephone band",
                              unit="take", disable=None):
        wave, _ = load_audio(root / "wave16k" / f"{take}.wav")  # a clear one-line error when it is missing
        enc = encoder.encode(np.asarray(telephone(wave), np.float32), hop_seconds=hop_seconds, parts=("emotion",))[0]
        encoded.append(enc)
        emotions += [emotion] * len(enc.emotion)
    windows = EncodedWindows(*(np.concatenate([getattr(e, k) for e in encoded]) for k in EncodedWindows.stored))
    return windows, np.asarray(emotions)


def real_voice_latents(encoder: SpeechLatentEncoder, names: list[str], stretches: int,
                       prosody_scale: float) -> tuple[EncodedWindows, np.ndarray]:
    """The real training voices ``names`` given each emotion at the corpus's ``prosody_scale``
    (:func:`emogesture.data.real_speech.training_voice_emotions`) -> their encoded windows (emotion latents and
    logits; one 10-s window each) and emotions ``[N]``."""
    waves, emotions = training_voice_emotions(names, stretches, prosody_scale)
    encoded = [encoder.encode(w, parts=("emotion",))[0] for w in waves]
    first = EncodedWindows(*(np.concatenate([getattr(e, k)[:1] for e in encoded]) for k in EncodedWindows.stored))
    return first, emotions
