"""Emotion along a timeline: ``--emotion "0:neutral,12:anger,30:sadness@0.5"``.

Each keyframe ``TIME:LABEL[@WEIGHT]`` (seconds from the start of the speech) holds until the next one.
``LABEL`` is an emotion label (the model's mean latent of that emotion, blended with the speech's own emotion
by ``WEIGHT``, 0-1, default 1), ``auto`` (the speech's own emotion, blended toward neutral where the voice
is unlike the training voices) or ``own`` (the speech's own emotion as heard). Before the first keyframe
the speech's own emotion holds, as with ``auto``.

The gesture model conditions each 10-s window on one emotion latent, so a window takes the keyframes in
force during it in proportion to the time each holds there (:meth:`EmotionTimeline.shares`); a change
then reaches the motion over the windows around it and their cross-faded seams, as smoothly as the seams.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from emogesture.errors import EmogestureError
from emogesture.pipeline.sampling import edit_emotion
from emogesture.types import EMOTIONS

OWN_MODES = ("auto", "own")


@dataclass(frozen=True)
class Keyframe:
    """From ``time`` seconds on: ``label`` (an emotion, ``auto`` or ``own``) at ``weight`` (0-1)."""

    time: float
    label: str
    weight: float = 1.0

    @property
    def text(self) -> str:
        """``TIME:LABEL[@WEIGHT]``, as written on the command line."""
        return f"{self.time:g}:{self.label}" + (f"@{self.weight:g}" if self.weight != 1.0 else "")

    @property
    def name(self) -> str:
        """``LABEL`` or ``LABEL xWEIGHT``, as shown in a video."""
        return self.label + (f" x{self.weight:g}" if self.weight != 1.0 else "")


def is_timeline(text: str | None) -> bool:
    """Whether an ``--emotion`` value is a timeline (it has ``TIME:`` keyframes) rather than a mode or label."""
    return text is not None and ":" in text


@dataclass(frozen=True)
class EmotionTimeline:
    """Keyframes in time order; the first at 0 s (an ``auto`` keyframe is put there when the text's first
    keyframe is later)."""

    keyframes: tuple[Keyframe, ...]

    @classmethod
    def parse(cls, text: str) -> "EmotionTimeline":
        """``"0:neutral,12:anger,30:sadness@0.5"`` -> a timeline; a one-line error naming the keyframe that is
        malformed, has an unknown label, a weight outside 0-1 or on ``auto``/``own``, or is not later than the
        one before."""
        frames: list[Keyframe] = []
        for part in (p.strip() for p in text.split(",")):
            where = f"--emotion {text!r}: keyframe {part!r}"
            time, sep, rest = part.partition(":")
            label, at, weight = rest.partition("@")
            label = label.strip().lower()
            try:
                t = float(time)
                w = float(weight) if at else 1.0
            except ValueError:
                raise EmogestureError(f"{where}: expected TIME:LABEL or TIME:LABEL@WEIGHT (seconds, 0-1)") from None
            if not sep or not np.isfinite(t) or t < 0:
                raise EmogestureError(f"{where}: expected TIME:LABEL with TIME in seconds from 0")
            if label not in EMOTIONS and label not in OWN_MODES:
                raise EmogestureError(f"{where}: unknown label {label!r}; use auto, own or one of "
                                      f"{', '.join(EMOTIONS)}")
            if not 0.0 <= w <= 1.0:
                raise EmogestureError(f"{where}: weight {w:g} must be between 0 and 1")
            if at and label in OWN_MODES:
                raise EmogestureError(f"{where}: a weight blends toward a label; {label} takes none")
            if frames and t <= frames[-1].time:
                raise EmogestureError(f"{where}: times must increase ({t:g} s after {frames[-1].time:g} s)")
            frames.append(Keyframe(t, label, w))
        if frames[0].time > 0:
            frames.insert(0, Keyframe(0.0, "auto"))
        return cls(tuple(frames))

    @property
    def text(self) -> str:
        return ",".join(k.text for k in self.keyframes)

    @property
    def tag(self) -> str:
        """The output names' part: ``0s-neutral_12s-anger_30s-sadnessx0.5``."""
        return "_".join(f"{k.time:g}s-{k.label}" + (f"x{k.weight:g}" if k.weight != 1.0 else "")
                        for k in self.keyframes)

    def check_duration(self, seconds: float, source: object) -> None:
        """A one-line error when a keyframe starts after the end of a ``seconds``-long recording."""
        late = [k for k in self.keyframes if k.time >= seconds]
        if late:
            raise EmogestureError(f"--emotion: keyframe {late[0].text!r} starts after the end of {source} "
                                  f"({seconds:.1f} s)")

    def shares(self, starts_s: list[float], window_s: float, duration_s: float) -> np.ndarray:
        """``[W, K]``: the share of window ``w`` (``[start, start + window_s]`` within the recording) during
        which keyframe ``k`` holds; each row sums to 1."""
        times = np.array([k.time for k in self.keyframes] + [np.inf])
        out = np.zeros((len(starts_s), len(self.keyframes)))
        for w, start in enumerate(starts_s):
            lo, hi = start, max(min(start + window_s, duration_s), start + 1e-6)
            out[w] = np.clip(np.minimum(times[1:], hi) - np.maximum(times[:-1], lo), 0.0, None) / (hi - lo)
        return out / out.sum(1, keepdims=True)

    def in_force(self, t: float) -> Keyframe:
        return [k for k in self.keyframes if k.time <= t][-1]

    def window_report(self, shares: np.ndarray) -> list[dict[str, float]]:
        """Per window, the keyframes in force and their shares (``{"anger": 0.7, "sadness x0.5": 0.3}``)."""
        return [{self.keyframes[k].name: round(float(v), 3) for k, v in enumerate(row) if v > 0} for row in shares]

    def video_labels(self) -> list[tuple[float, str]]:
        """``(from seconds, emotion shown)`` for each keyframe."""
        return [(k.time, {"auto": "own (auto)", "own": "own (own)"}.get(k.label, k.name)) for k in self.keyframes]


def timeline_latents(timeline: EmotionTimeline, shares: np.ndarray, own: np.ndarray, auto: np.ndarray,
                     means: dict[str, list[float]]) -> np.ndarray:
    """Emotion latents ``[W, D]`` of a timeline: for keyframe ``k`` a window's latent is its ``own`` or
    ``auto`` latent (``[W, D]`` each), or ``(1 − weight) · auto + weight · mean[label]``; a window takes the
    keyframes by their ``shares [W, K]``."""
    out = np.zeros_like(own, dtype=np.float64)
    for k, frame in enumerate(timeline.keyframes):
        if frame.label == "own":
            latent = own
        elif frame.label == "auto":
            latent = auto
        else:
            if frame.label not in means:
                raise EmogestureError(f"--emotion: the model has no mean latent for {frame.label!r}")
            target = np.broadcast_to(np.asarray(means[frame.label], np.float32), auto.shape)
            latent = edit_emotion(auto, target, frame.weight)
        out += shares[:, k:k + 1] * latent
    return out.astype(np.float32)
