"""The emotion perception's read-out model: which emotion a speech model hears in each window, and whether its
emotion latent can be trusted there. How ``generate`` acts on it is :mod:`emogesture.pipeline.perception`; how
it is measured, :mod:`emogesture.train.perception`.

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
everywhere or weighted by the trust (`experiments/speech_training/reports/speech_tuned/perception_readout_val.md`).

A voice pitched unlike the training voices is read partly by its pitch: the corpus gives its emotions
their own pitch, so a voice moved 4 semitones down sounds sadder or more contemptuous to the model. The
generation setting ``perception_semitones`` (3 by default) has the emotion encoder hear each window
three times, as recorded and with the voice (pitch and formants, tempo kept) moved that many semitones up
and down; the probabilities reported are the mean of the three readings (:func:`heard_probabilities`). On
the val split's held-out voices this was right more often in every pitch condition and as recorded
(`experiments/perception/reports/perception_hearings/`). Only what is heard changes; the trust and the latents the
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

A telephone band (below 300 Hz and above 3.4 kHz taken away) moves every window's emotion latent, and so do a
quieter recording and one in noise; the corpus's emotion means alone then read held-out voices played through
such conditions right less often than the same voices as recorded. A calibration with ``--condition-means``
gives each emotion one more mean per condition, of the training takes heard through it
(:func:`emogesture.train.perception.condition_latents`: a simulated telephone band, 6-14 dB quieter, white
noise at 8-16 dB SNR), which only the read-out uses (:meth:`EmotionPerception.read_range`: the head plus the
posterior summed over each emotion's means, within the same threshold; the fields ``band_labels`` and
``band_means`` hold them). The trust, the neutral mean and the latents ``auto`` animates stay the corpus's: such a
recording is heard better, not animated differently (`experiments/perception/README.md`, "Telephone-band means
in the read-out" and "Condition means"; measured on simulated conditions only, as no real recording of them
with a known emotion is at hand).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from emogesture.diffusion.residual import shrunk_covariance
from emogesture.errors import EmogestureError
from emogesture.types import EMOTIONS

COMPONENTS = 32
ARRAYS = ("means", "axes", "variances")  # a LatentRange's arrays
#: the weights-file names of a perception's arrays begin so (EmotionPerception.to_state)
TENSOR_PREFIX = "emotion_perception."


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
    (a probabilistic-PCA approximation, small enough to ship with the model). The distance of ``z`` to a class
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

    def to_state(self, name: str) -> tuple[dict, dict[str, np.ndarray]]:
        """(the scalars, for a model file's JSON; the arrays as ``name.means``, ``name.axes``, ``name.variances``)."""
        return ({"rest": self.rest, "threshold": self.threshold},
                {f"{name}.{k}": getattr(self, k) for k in ARRAYS})

    @classmethod
    def from_state(cls, record: dict, arrays: dict[str, np.ndarray], name: str) -> "LatentRange":
        """The inverse of :meth:`to_state`; a file written before the arrays were tensors holds them in ``record``."""
        return cls(*(np.asarray(arrays[f"{name}.{k}"] if f"{name}.{k}" in arrays else record[k], np.float64)
                     for k in ARRAYS), float(record["rest"]), float(record["threshold"]))


@dataclass
class LinearReadout:
    """A multinomial logistic regression on standardised features: ``softmax(weight @ ((x - mean) / scale) +
    bias)`` over :attr:`labels` (the emotions it was fitted on; the others get probability 0). The read-out of a
    front end trained on real speech (:mod:`emogesture.pipeline.voice_features`)."""

    labels: list[str]
    mean: np.ndarray  # [F]
    scale: np.ndarray  # [F]
    weight: np.ndarray  # [K, F]
    bias: np.ndarray  # [K]
    front_end: str = "whisper-tiny.en"
    info: dict = field(default_factory=dict)

    def log_probs(self, features: np.ndarray) -> np.ndarray:
        """Features ``[W, F]`` -> log-probabilities ``[W, 8]`` over ``EMOTIONS``."""
        x = (np.asarray(features, np.float64) - self.mean) / self.scale
        fitted = log_softmax(x @ self.weight.T + self.bias)
        out = np.full((len(x), len(EMOTIONS)), -np.inf)
        out[:, [EMOTIONS.index(label) for label in self.labels]] = fitted
        return out

    def to_state(self) -> tuple[dict, dict[str, np.ndarray]]:
        """Its labels and front end (JSON) and its arrays (named ``heard.<array>``)."""
        return ({"labels": list(self.labels), "front_end": self.front_end, "info": self.info},
                {f"heard.{k}": getattr(self, k) for k in ("mean", "scale", "weight", "bias")})

    @classmethod
    def from_state(cls, record: dict, arrays: dict[str, np.ndarray]) -> "LinearReadout":
        """The inverse of :meth:`to_state`."""
        try:
            values = {k: np.asarray(arrays[f"heard.{k}"], np.float64) for k in ("mean", "scale", "weight", "bias")}
        except KeyError as e:
            raise EmogestureError(f"emotion perception: the read-out's array {e} is missing") from None
        readout = cls(list(record["labels"]), front_end=record.get("front_end", "whisper-tiny.en"),
                      info=dict(record.get("info", {})), **values)
        if readout.weight.shape != (len(readout.labels), len(readout.mean)) or readout.bias.shape != (len(readout.labels),):
            raise EmogestureError(f"emotion perception: a read-out of {len(readout.labels)} emotions with weights "
                                  f"{readout.weight.shape} and bias {readout.bias.shape}")
        return readout


@dataclass
class EmotionPerception:
    """Where a speech model's emotion and style latents lie on its training speech (module docstring)."""

    labels: list[str]  # the emotion of each of ``emotion.means`` (an emotion may have several: real voices')
    emotion: LatentRange  # emotion latent around the emotion means
    voice: LatentRange  # style latent around the training speakers' means
    info: dict  # how it was measured (splits, windows, quantile)
    temperature: float = 1.0  # divides the read-out's summed log-probabilities within the range (read)
    #: the emotion of each of ``band_means``: each emotion's mean of the training windows heard through a
    #: recording condition (a telephone band, quieter, in noise), which only the read-out uses (module
    #: docstring); empty without them
    band_labels: list[str] = field(default_factory=list)
    band_means: np.ndarray | None = None  # [B, D]
    #: how many of ``voice.means`` are the training corpus's speakers (the real speakers' follow); None: all
    corpus_voices: int | None = None
    #: the read-out of a front end trained on real speech (what is heard where its features are at hand)
    heard: LinearReadout | None = None

    def trust(self, emotion: np.ndarray, style: np.ndarray) -> np.ndarray:
        """Per-window trust ``[W]``: the smaller of the emotion's and the voice's."""
        return np.minimum(self.emotion.trust(emotion), self.voice.trust(style))

    def read_range(self) -> LatentRange:
        """The emotion range the read-out uses: :attr:`emotion` with the condition means beside its own
        (the same spread and threshold); :attr:`emotion` itself without them."""
        if self.band_means is None or not len(self.band_labels):
            return self.emotion
        return replace(self.emotion, means=np.concatenate([self.emotion.means, self.band_means]))

    def summed(self, emotion: np.ndarray, logits: np.ndarray) -> np.ndarray:
        """The head's log-probabilities plus the emotion means' log-posteriors, ``[W, 8]`` over ``EMOTIONS``
        (an emotion with several means, the real voices' and the conditions': their posteriors summed;
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

    def heard_latents(self, probs: np.ndarray) -> np.ndarray:
        """Probabilities ``[W, 8]`` over ``EMOTIONS`` -> ``[W, D]``: the corpus's emotion means weighted by them
        (an emotion without a mean left out, the rest renormalised): the latent of the emotion heard."""
        first = {label: self.labels.index(label) for label in self.labels}
        ks = [k for k, e in enumerate(EMOTIONS) if e in first]
        weights = np.asarray(probs, np.float64)[:, ks]
        weights = weights / np.maximum(weights.sum(1, keepdims=True), 1e-12)
        return weights @ self.emotion.means[[first[EMOTIONS[k]] for k in ks]]

    def typical_speaker(self) -> int:
        """Index (into ``voice.means``) of the training speaker whose mean style latent lies nearest the
        centre of all the corpus speakers' means, in the voice's own distance."""
        corpus = self.voice.means[: self.corpus_voices]
        return int(self.voice.distances(corpus.mean(0, keepdims=True))[0][: len(corpus)].argmin())

    def typical_style(self) -> np.ndarray:
        """The mean style latent ``[D]`` of :meth:`typical_speaker`."""
        return self.voice.means[self.typical_speaker()]

    def to_state(self) -> tuple[dict, dict[str, np.ndarray]]:
        """What a speech model file stores of it: the labels, scalars and how it was measured (JSON, the
        metadata's ``emotion_perception``) and its arrays ``[.., D]`` in float64 (tensors of the weights file,
        named ``emotion_perception.<range>.<array>``; :func:`emogesture.checkpoints.save_model`)."""
        emotion, emotion_arrays = self.emotion.to_state("emotion")
        voice, voice_arrays = self.voice.to_state("voice")
        record = {"labels": list(self.labels), "emotion": emotion, "voice": voice, "info": self.info,
                  "temperature": self.temperature}
        arrays = {**emotion_arrays, **voice_arrays}
        if self.corpus_voices is not None:
            record["corpus_voices"] = self.corpus_voices
        if self.band_means is not None:
            record["band_labels"] = list(self.band_labels)
            arrays["band_means"] = self.band_means
        if self.heard is not None:
            record["heard"], heard_arrays = self.heard.to_state()
            arrays.update(heard_arrays)
        return record, {f"{TENSOR_PREFIX}{k}": np.asarray(v, np.float64) for k, v in arrays.items()}

    @classmethod
    def from_state(cls, record: dict, tensors: dict[str, np.ndarray]) -> "EmotionPerception":
        """The inverse of :meth:`to_state`: the JSON record and the weights file's tensors (those not named
        ``emotion_perception.*`` are ignored)."""
        arrays = {k[len(TENSOR_PREFIX):]: np.asarray(v) for k, v in tensors.items() if k.startswith(TENSOR_PREFIX)}
        emotion = LatentRange.from_state(record["emotion"], arrays, "emotion")
        voice = LatentRange.from_state(record["voice"], arrays, "voice")
        band = arrays.get("band_means", record.get("band_means"))
        labels = list(record.get("band_labels", []))
        if band is not None:
            band = np.asarray(band, np.float64)
            if band.ndim != 2 or band.shape[1:] != emotion.means.shape[1:] or len(band) != len(labels):
                raise EmogestureError(f"emotion perception: {len(labels)} condition labels for condition means of "
                                      f"shape {band.shape}; the emotion means are {emotion.means.shape}")
        heard = LinearReadout.from_state(record["heard"], arrays) if record.get("heard") else None
        return cls(list(record["labels"]), emotion, voice, dict(record.get("info", {})),
                   float(record.get("temperature", 1.0)), labels, band, record.get("corpus_voices"), heard)
