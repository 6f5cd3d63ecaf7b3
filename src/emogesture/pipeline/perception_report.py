"""What ``generate`` tells a user it heard: the emotion perceived in each window of one recording, its one-line
summary, the details behind it (``--verbose``) and the per-window JSON written beside the animation
(:class:`PerceivedEmotion`)."""

from __future__ import annotations

import json
import re
from collections import Counter
from dataclasses import dataclass

import numpy as np

from emogesture.types import EMOTIONS

#: the longest file name a summary shows whole (a longer one keeps its end)
NAME_CHARS = 32


def short_name(source: str) -> str:
    """A recording's file name for a one-line summary (``talk.flac 10-20 s`` keeps its span), at most
    :data:`NAME_CHARS` characters."""
    span = re.search(r" [0-9.]+-[0-9.]+ s$", str(source))
    path = str(source)[:span.start()] if span else str(source)
    name = path.replace("\\", "/").rsplit("/", 1)[-1] + (span.group(0) if span else "")
    return name if len(name) <= NAME_CHARS else "…" + name[-(NAME_CHARS - 1):]


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
        """One short line: the emotion heard and what ``mode`` (``auto``/``own``) did about windows beyond the
        calibrated range, the recording named by its file name; :meth:`details` says the rest."""
        label, count = self.majority
        n = len(self.labels)
        text = f"{short_name(self.source)}: heard {label} in {count}/{n} windows (p {self.confidence:.2f})"
        if self.neutral_reference is not None:
            text += f" against {short_name(self.neutral_reference)}"
        if self.trust is None:
            return text + "; no calibration: used as heard"
        low = int((self.trust < 1.0).sum())
        if mode == "auto" and low:
            far = int((self.distance[:, 1] > 1.0).sum())
            return text + f"; auto: {low} toward neutral" + (f", {far} fallback style" if far else "")
        if low:
            return text + f"; {low} beyond the training voices, kept"
        return text + "; every window trusted"

    def details(self, mode: str) -> list[str]:
        """What :meth:`summary` leaves out, a sentence a line: how the recording was heard and why windows were
        blended (``generate --verbose`` prints them)."""
        n = len(self.labels)
        lines = []
        if self.noise_suppressed > 0:
            lines.append(f"heard with its steady background noise taken out ({self.noise_suppressed:.0%})")
        if self.digital_silence_s > 0:
            lines.append(f"its {self.digital_silence_s:.1f} s of digital silence heard as the recording's own quiet")
        if self.neutral_reference is not None:
            lines.append(f"read against the speaker's neutral voice in {self.neutral_reference}")
        if self.trust is None:
            return lines + ["this speech model has no perception calibration: its emotion latent is used as is"]
        low = int((self.trust < 1.0).sum())
        real = int((self.real_voices > 0.5).sum()) if self.real_voices is not None else 0
        if mode == "auto" and real:
            lines.append(f"{real} of {n} windows sound more like the real voices the perception knows than the "
                         "training voices and are animated with the training voices' latent of the emotion heard")
        if mode == "auto" and low:
            far = int((self.distance[:, 1] > 1.0).sum())
            lines.append(f"in {low} of {n} windows the voice or its emotion is unlike the training speech (beyond "
                         "the calibrated range), so their emotion is blended toward neutral (--emotion own keeps it)")
            if far:
                lines.append(f"in {far} the voice is unlike every training voice, so its gesture style is blended "
                             "toward the gesture model's fallback style")
        elif low:
            lines.append(f"{low} of {n} windows lie outside the training voices' range (kept: --emotion own)")
        return lines

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
