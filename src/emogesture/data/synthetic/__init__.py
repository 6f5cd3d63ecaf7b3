"""Synthetic BEAT2-layout corpus: real speech synthesis plus procedural, speech-timed SMPL-X gestures
with known emotion, speaker and content factors (docs/design.md, 'Synthetic corpus')."""

from emogesture.data.synthetic.corpus import CorpusConfig, CorpusSummary, build_corpus, plan_takes, text_split
from emogesture.data.synthetic.factors import EMOTION_FACTORS, VOICES, make_speaker

__all__ = [
    "EMOTION_FACTORS",
    "VOICES",
    "CorpusConfig",
    "CorpusSummary",
    "build_corpus",
    "make_speaker",
    "plan_takes",
    "text_split",
]
