"""Quadruple sampling for the speech disentangler (docs/design.md, 'Speech disentanglement model'; paper supp. B.4).

A training sample is four windows ``(a1, a2, a3, a4) = (c1 s1, c2 s1, c1 s2, c2 s2)``: one emotion,
two texts ``c1 != c2`` of that emotion, two speakers ``s1 != s2`` who both spoke both texts. The
window of a text is taken at the same position (k-th window) for both speakers, so the spoken
content is approximately aligned.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass

import numpy as np

from emogesture.data.cache import SplitWindows
from emogesture.errors import EmogestureError


@dataclass(frozen=True)
class Quadruple:
    """Window indices ``[4]`` in the order (c1 s1, c2 s1, c1 s2, c2 s2), their emotion and speakers."""

    indices: tuple[int, int, int, int]
    emotion: int
    speakers: tuple[int, int, int, int]


class QuadrupleIndex:
    """Which quadruples a split of windows offers, and seeded draws from them."""

    def __init__(self, windows: SplitWindows, first_texts: set[int] | None = None) -> None:
        """``windows``: anything with ``text``, ``speaker_id``, ``emotion``, ``start_s`` arrays ``[W]``.

        ``first_texts``: only pairs whose first text ``c1`` is in this set (e.g. held-out texts,
        paired with training texts of the same emotion as ``c2``).
        """
        by_text_speaker: dict[tuple[int, int], list[tuple[float, int]]] = defaultdict(list)
        text_emotion: dict[int, int] = {}
        for i in range(len(windows.text)):
            text, spk = int(windows.text[i]), int(windows.speaker_id[i])
            by_text_speaker[(text, spk)].append((float(windows.start_s[i]), i))
            text_emotion.setdefault(text, int(windows.emotion[i]))
        self.windows = {k: [i for _, i in sorted(v)] for k, v in by_text_speaker.items()}
        speakers_of: dict[int, set[int]] = defaultdict(set)
        for text, spk in self.windows:
            speakers_of[text].add(spk)
        texts_by_emotion: dict[int, list[int]] = defaultdict(list)
        for text, emo in sorted(text_emotion.items()):
            texts_by_emotion[emo].append(text)
        # (emotion, c1, c2, [speakers who spoke both]) with at least two such speakers
        self.pairs: list[tuple[int, int, int, tuple[int, ...]]] = []
        for emo, texts in sorted(texts_by_emotion.items()):
            for a in texts:
                for b in texts:
                    common = tuple(sorted(speakers_of[a] & speakers_of[b]))
                    if first_texts is not None and a not in first_texts:
                        continue
                    if a != b and len(common) >= 2:
                        self.pairs.append((emo, a, b, common))
        if not self.pairs:
            raise EmogestureError(
                "no quadruples: need two texts of one emotion each spoken by at least two speakers"
            )

    def draw(self, rng: np.random.Generator) -> Quadruple:
        """One quadruple, uniformly over (emotion, text pair), then speakers and window position."""
        emo, c1, c2, common = self.pairs[rng.integers(len(self.pairs))]
        s1, s2 = rng.choice(common, size=2, replace=False)
        k1 = rng.integers(min(len(self.windows[(c1, s1)]), len(self.windows[(c1, s2)])))
        k2 = rng.integers(min(len(self.windows[(c2, s1)]), len(self.windows[(c2, s2)])))
        idx = (
            self.windows[(c1, s1)][k1],
            self.windows[(c2, s1)][k2],
            self.windows[(c1, s2)][k1],
            self.windows[(c2, s2)][k2],
        )
        return Quadruple(tuple(int(i) for i in idx), int(emo), (int(s1), int(s1), int(s2), int(s2)))


@dataclass
class WindowLabels:
    """The label columns of one or more splits, concatenated: what :class:`QuadrupleIndex` reads."""

    text: np.ndarray
    speaker_id: np.ndarray
    emotion: np.ndarray
    start_s: np.ndarray

    @classmethod
    def concat(cls, *splits: SplitWindows) -> "WindowLabels":
        return cls(*(np.concatenate([getattr(s, k) for s in splits]) for k in ("text", "speaker_id", "emotion", "start_s")))
