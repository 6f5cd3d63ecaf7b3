"""Emotion perception: which emotion the speech model hears in each window, and whether its emotion
latent can be trusted there.

The speech model learns emotion from the training voices only. On a voice unlike them (a real
recording, another synthesiser) its emotion latent can land far from every emotion it knows, and the
gesture model would then animate an emotion nobody spoke. So a speech model carries, in its
``extra["emotion_perception"]``, a description of where its emotion latents lie on training speech:

- the mean latent of each emotion on the training windows, and the pooled within-emotion standard
  deviation of each latent dimension;
- a window's *distance* is the root mean square of its standardised difference to the nearest
  emotion mean, ``min_k sqrt(mean(((e − μ_k) / σ)²))`` (a diagonal Mahalanobis distance per dimension);
- the *threshold* is a high quantile (default 0.99) of that distance over held-out windows (texts the
  speech model never trained on), so about 1 % of in-distribution windows exceed it.

With ``--emotion auto`` (the default of ``emogesture generate``) a window's trust is 1 up to the
threshold and falls linearly to 0 at twice the threshold; its emotion latent is blended toward the
neutral mean by ``1 − trust``. ``--emotion own`` keeps the raw latent.
"""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from os import PathLike
from pathlib import Path

import numpy as np

from emogesture.checkpoints import load_model, model_paths, save_model
from emogesture.data.beat import EMOTIONS
from emogesture.data.cache import open_cache
from emogesture.errors import EmogestureError, InputFileError, OutputExistsError
from emogesture.pipeline.speech import EncodedWindows, SpeechLatentEncoder

TRUST_QUANTILE = 0.99


@dataclass
class EmotionPerception:
    """Where a speech model's emotion latents lie on its training speech (see the module docstring)."""

    labels: list[str]
    means: np.ndarray  # [K, D] per-emotion mean latent (training windows)
    scale: np.ndarray  # [D] pooled within-emotion standard deviation
    threshold: float  # distance above which trust starts to fall
    info: dict  # how it was measured (splits, windows, quantile)

    def distances(self, emotion: np.ndarray) -> np.ndarray:
        """Emotion latents ``[W, D]`` -> standardised RMS distance to each emotion mean ``[W, K]``."""
        diff = (np.asarray(emotion, np.float64)[:, None, :] - self.means[None]) / self.scale
        return np.sqrt((diff * diff).mean(-1))

    def trust(self, emotion: np.ndarray) -> np.ndarray:
        """Per-window trust ``[W]`` in [0, 1]: 1 up to the threshold, 0 from twice the threshold."""
        d = self.distances(emotion).min(1)
        return np.clip(2.0 - d / self.threshold, 0.0, 1.0)

    def neutral(self) -> np.ndarray:
        return self.means[self.labels.index("neutral")]

    def to_dict(self) -> dict:
        return {"labels": list(self.labels), "means": self.means.tolist(), "scale": self.scale.tolist(),
                "threshold": float(self.threshold), "info": self.info}

    @classmethod
    def from_dict(cls, d: dict) -> "EmotionPerception":
        return cls(list(d["labels"]), np.asarray(d["means"], np.float64), np.asarray(d["scale"], np.float64),
                   float(d["threshold"]), dict(d.get("info", {})))


def fit_perception(train_emotion: np.ndarray, train_labels: np.ndarray, held_out_emotion: np.ndarray,
                   quantile: float = TRUST_QUANTILE) -> EmotionPerception:
    """Class means and pooled spread from training latents ``[N, D]`` with labels ``[N]`` (indices into
    ``EMOTIONS``), and the trust threshold as the ``quantile`` of held-out windows' distances."""
    e = np.asarray(train_emotion, np.float64)
    y = np.asarray(train_labels)
    present = sorted(set(y.tolist()))
    if EMOTIONS.index("neutral") not in present:
        raise EmogestureError("emotion perception needs neutral training windows")
    means = np.stack([e[y == k].mean(0) for k in present])
    within = e - means[np.searchsorted(present, y)]
    scale = np.sqrt((within * within).mean(0)).clip(1e-6)
    p = EmotionPerception([EMOTIONS[k] for k in present], means, scale, 1.0, {})
    d = p.distances(held_out_emotion).min(1)
    p.threshold = float(np.quantile(d, quantile))
    p.info = {"train_windows": int(len(e)), "held_out_windows": int(len(d)), "quantile": float(quantile),
              "held_out_distance_median": float(np.median(d))}
    return p


def perception_of(encoder: SpeechLatentEncoder) -> EmotionPerception | None:
    stored = encoder.loaded.extra.get("emotion_perception")
    return EmotionPerception.from_dict(stored) if stored else None


@dataclass
class PerceivedEmotion:
    """What the speech model heard in each window of one audio."""

    source: str
    starts_s: list[float]
    labels: list[str]  # per window, the classifier's emotion
    probabilities: np.ndarray  # [W, 8] softmax of the emotion logits
    distance: np.ndarray | None  # [W] distance to the nearest emotion mean (None: model not calibrated)
    trust: np.ndarray | None  # [W]

    @property
    def majority(self) -> tuple[str, int]:
        return Counter(self.labels).most_common(1)[0]

    @property
    def confidence(self) -> float:
        """Mean probability of the majority emotion over the windows."""
        label, _ = self.majority
        return float(self.probabilities[:, EMOTIONS.index(label)].mean())

    def summary(self, mode: str) -> str:
        label, count = self.majority
        n = len(self.labels)
        text = (f"{self.source}: perceived emotion {label} ({count} of {n} window{'s' * (n != 1)}, "
                f"mean probability {self.confidence:.2f})")
        if self.trust is None:
            return text + "; this speech model has no perception calibration, its emotion latent is used as is"
        low = int((self.trust < 1.0).sum())
        if mode == "auto" and low:
            return (text + f"; in {low} of {n} windows the voice is unlike the training voices (distance above "
                    "the calibrated threshold), so their emotion is blended toward neutral (--emotion own keeps it)")
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
                row["distance"] = round(float(self.distance[i]), 4)
                row["trust"] = round(float(self.trust[i]), 4)
            rows.append(row)
        label, count = self.majority
        return json.dumps({"source": self.source, "emotion": label, "windows_agreeing": count,
                           "confidence": round(self.confidence, 4), "windows": rows}, indent=1) + "\n"


def perceive(enc: EncodedWindows, starts_s: list[float], perception: EmotionPerception | None,
             source: str) -> PerceivedEmotion:
    logits = np.asarray(enc.emotion_logits, np.float64)
    probs = np.exp(logits - logits.max(1, keepdims=True))
    probs /= probs.sum(1, keepdims=True)
    labels = [EMOTIONS[int(k)] for k in probs.argmax(1)]
    distance = trust = None
    if perception is not None:
        distance = perception.distances(enc.emotion).min(1)
        trust = perception.trust(enc.emotion)
    return PerceivedEmotion(source, list(starts_s), labels, probs, distance, trust)


def auto_emotion(emotion: np.ndarray, perception: EmotionPerception | None) -> np.ndarray:
    """Emotion latents ``[W, D]`` blended toward the neutral mean by ``1 − trust`` (``--emotion auto``);
    unchanged when the model has no perception calibration."""
    if perception is None:
        return emotion
    w = perception.trust(emotion)[:, None]
    return (w * emotion + (1.0 - w) * perception.neutral()[None]).astype(np.float32)


def calibrate_perception_run(run: str | PathLike[str], cache_dir: str | PathLike[str], out: str | PathLike[str],
                             split: str = "val", quantile: float = TRUST_QUANTILE,
                             overwrite: bool = False) -> EmotionPerception:
    """Write a copy of the speech model of ``run`` to ``out`` with its emotion perception: means and
    spread from the cache's ``train`` windows, the threshold from ``split`` (which the model must not
    have trained on; its run records the training splits)."""
    if not 0.5 <= quantile < 1.0:
        raise EmogestureError(f"quantile {quantile}: must be in [0.5, 1)")
    if split in ("train", "test"):
        raise EmogestureError(f"--split {split}: calibrate on held-out windows that are not the test split (e.g. val)")
    if not overwrite:
        for p in model_paths(out):
            if p.exists():
                raise OutputExistsError(p)
    loaded = load_model(run, "speech")
    trained_on = trained_splits(loaded)
    if split in trained_on:
        raise InputFileError(loaded.path, f"was trained on the {split} split ({', '.join(trained_on)}); "
                             "calibrate on windows it never saw")
    encoder = SpeechLatentEncoder(loaded)
    cache = open_cache(cache_dir)
    train = encoder.encode_split(cache, "train")
    held = encoder.encode_split(cache, split)
    perception = fit_perception(train.emotion, np.asarray(cache.split("train").emotion), held.emotion, quantile)
    perception.info.update(split=split, trained_on=trained_on)
    extra = {**loaded.extra, "train_splits": trained_on, "emotion_perception": perception.to_dict()}
    save_model(out, "speech", loaded.model, loaded.config, extra)
    return perception


def trained_splits(loaded) -> list[str]:
    """The cache splits a speech model trained on: from its file, else from its run folder's ``run.json``."""
    if "train_splits" in loaded.extra:
        return list(loaded.extra["train_splits"])
    try:
        blob = json.loads((Path(loaded.path).parent / "run.json").read_text())
        return list(blob["config"]["train_splits"])
    except (OSError, ValueError, KeyError, TypeError):
        raise InputFileError(loaded.path, "does not record the splits it was trained on (no train_splits, no "
                             "run.json beside it)") from None
